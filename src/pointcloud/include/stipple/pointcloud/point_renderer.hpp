#pragma once
// The point rendering pipeline (seed 000, section 6; seed 004, section 6) as render-graph passes:
//
//   clod (compute, --clod-k > 0)   eq. 6-9 per point; survivors' indices appended with atomics,
//                                  indirect draw arguments per chunk
//   points (naive)                 one depth-tested pass, opaque discs/squares
//   splat-depth + splat-accumulate (blend) Botsch et al.'s three passes: a depth pre-pass pushed
//                                  back by `blend_depth` of the depth, additive weighted colours
//                                  into a transient RGBA16Float texture
//   resolve                        normalisation (sum / weight) merged with eye-dome lighting
//                                  (eqs. 10-12); skipped for naive without EDL
//   points-translucent + points-composite  clouds with translucent points in the RGB mode
//                                  (CloudAttributes::has_translucent): the passes above skip
//                                  them, then weighted blended order-independent transparency
//                                  (McGuire and Bavoil 2013) adds the translucent points in front
//                                  of the opaque depth into a transient RGBA16Float texture
//                                  (colour times w and w, w = -ln(1 - alpha)), and a full-screen
//                                  pass lays their average colour over the image by the coverage
//                                  1 - exp(-sum w) (1 minus the product of their 1 - alpha), after
//                                  the resolve: EDL shades the opaque points only
//
// Points are pulled from storage buffers (no vertex buffers, no instancing): 6 vertices per point,
// vertex_index / 6 is the point (or its survivor slot), vertex_index % 6 the quad corner.
// Instanced 4-vertex quads ran at 150M points/s on an H200; tiny instances waste most of the
// vertex wavefront on NVIDIA.
//
// Camera-relative throughout (seed 000, section 5): chunk origins minus the camera position in
// double, cast to float per frame; the view-projection holds the rotation only.
//
// Colour is computed in the shader from the packed attributes, so colour modes and ranges are
// uniforms: switching them in the viewer costs nothing.
#include <algorithm>
#include <array>
#include <string>
#include <vector>

#include <glm/vec2.hpp>
#include <glm/vec3.hpp>

#include "stipple/math/camera.hpp"
#include "stipple/pointcloud/filters.hpp"
#include "stipple/pointcloud/point_cloud.hpp"
#include "stipple/pointcloud/sky.hpp"
#include "stipple/renderer/gpu.hpp"
#include "stipple/renderer/gpu_timer.hpp"
#include "stipple/renderer/render_graph.hpp"
#include "stipple/renderer/suballocator.hpp"

namespace stipple::pc {

enum class SplatMode { Naive, Blend };
// fixed: `point_size` pixels; attenuated: the chunk's spacing * size_scale in world units, so
// pixels shrink with distance; adaptive: like attenuated but grown where CLOD thinned the points
// (spacing / sqrt(kept fraction)), so the surface stays closed (seed 004, 6.3).
enum class PointSizeMode { Fixed, Attenuated, Adaptive };

// Every option of the point pipeline; `stipple render` and `stipple view` parse the same flags
// into it (app/point_options.hpp).
struct PointRenderSettings {
  // Colour (seed 004, 6.2).
  ColorMode color = ColorMode::Auto;
  glm::vec3 constant_color{1.0f, 1.0f, 1.0f};
  // Ramp ranges; min >= max means "from the data" (2nd-98th percentile).
  glm::dvec2 elevation_range{0.0, 0.0};  // source Z units
  glm::dvec2 intensity_range{0.0, 0.0};
  // Size.
  PointSizeMode size_mode = PointSizeMode::Fixed;
  float point_size = 0.0f;  // fixed mode, pixels; 0 = auto_point_size()
  float size_scale = 1.6f;  // attenuated/adaptive: world size = spacing * size_scale
  float max_point_px = 64.0f;
  bool round = true;  // discs instead of squares (from 3 px up)
  // CLOD (seed 000, 6.1): quality factor k of s_target = d * k; 0 = off.
  float clod_k = 0.0f;
  // Splatting (seed 000, 6.2).
  SplatMode splat = SplatMode::Blend;
  float blend_depth = 0.01f;  // depth pre-pass pushes fragments back by this fraction
  // Eye-dome lighting (seed 000, 6.3).
  bool edl = true;
  float edl_radius = 1.4f;     // pixels
  float edl_strength = 60.0f;  // k of eq. 11
  glm::vec3 background{0.07f, 0.08f, 0.1f};
  // The Nishita sky instead of the background colour (sky.hpp); off by default. The billboard
  // path then always runs its resolve, where the sky is drawn.
  SkySettings sky;
  // Filters and clipping (filters.hpp), tested per point in the vertex shader: changing them
  // re-uploads nothing. GPS-time and point-source filters read the chunks' extras (uploaded by
  // upload_point_extras), the others the packed attribute word.
  PointFilter filter;
  ClipRegion clip;
  glm::vec4 highlight{1.0f, 0.85f, 0.1f, 0.65f};  // Highlight mode: tint rgb, strength a
};

// The point diameter the compute rasterizer dilates to: the fixed size in pixels (attenuated
// and adaptive sizes are the billboard path's), at least 1.
float compute_point_size(const PointRenderSettings& settings);

// The shading the billboard path would use for `settings` over a cloud with `attributes`
// (explicit ramp ranges, else the attributes' percentiles); its mode may still be Auto.
PointShading point_shading(const PointRenderSettings& settings, const CloudAttributes& attributes);

SplatMode parse_splat_mode(const std::string& name);
PointSizeMode parse_point_size_mode(const std::string& name);

struct GpuPointCloud {
  struct Chunk {
    // Where the passes bind the points (array<Point>, PointChunk::Vertex) and the CLOD output
    // (u32 indices into the points): the chunk's own buffers below (upload_chunk), or ranges of
    // suballocator pages (upload_chunk_paged). Offsets are storage-binding aligned. Not owned.
    WGPUBuffer points_buffer = nullptr, survivors_buffer = nullptr;
    uint64_t points_offset = 0, survivors_offset = 0;
    gpu::Buffer points, survivors;  // upload_chunk's own buffers; empty for paged chunks
    gpu::SubAllocation range, survivors_range;  // a paged chunk's ranges
    uint32_t count = 0;
    glm::dvec3 origin{0.0};
    double spacing = 0.0;  // s_native of CLOD
    // PointChunk::extras, bound only while a GPS-time or point-source filter is on (null:
    // not uploaded, or the source has none); GPS times are relative to gps_origin.
    gpu::Buffer extras;
    double gps_origin = 0.0;
    // Created on first draw, for the pipelines' layouts.
    gpu::BindGroup points_group, survivors_group, clod_group, points_extras_group;
  };
  std::vector<Chunk> chunks;
  uint64_t point_count = 0;
  CloudAttributes attributes;
  // CLOD indirect draw arguments: one 256-byte slot per chunk (storage-binding alignment),
  // {vertex_count, instance_count, first_vertex, first_instance}; vertex_count / 6 survivors.
  gpu::Buffer clod_args;
  uint32_t clod_args_stride = 256;
  const void* bind_groups_for = nullptr;  // the PointPipelines the groups were made for
};

// Uploads every chunk into storage buffers, split where a chunk exceeds the device's
// maxStorageBufferBindingSize (or 8M points: one dispatch of the CLOD pass). Also allocates the
// CLOD survivor buffers (4 bytes per point).
// Incremental upload (streaming, benchmarks): chunks one at a time, then finish_upload() once
// to size the per-chunk CLOD arguments.
void upload_chunk(gpu::Context& ctx, GpuPointCloud& gpu_cloud, const PointChunk& chunk);
// The most points one GPU chunk holds on this device (larger chunks are split).
uint64_t max_gpu_chunk_points(const gpu::Context& ctx);
// Splits `chunk` into GPU pieces of at most `max_points` points sharing its origin and spacing;
// `store(piece, first_vertex)` gives each its buffers, then the piece joins the cloud.
template <typename Store>
void append_chunk_pieces(GpuPointCloud& cloud, const PointChunk& chunk, uint64_t max_points,
                         Store store) {
  for (size_t first = 0; first < chunk.vertices.size(); first += max_points) {
    GpuPointCloud::Chunk c;
    c.count = uint32_t(std::min<uint64_t>(max_points, chunk.vertices.size() - first));
    c.origin = chunk.origin;
    c.spacing = chunk.spacing > 0 ? chunk.spacing : 1.0;
    store(c, chunk.vertices.data() + first);
    cloud.point_count += c.count;
    cloud.chunks.push_back(std::move(c));
  }
}
void finish_upload(gpu::Context& ctx, GpuPointCloud& gpu_cloud);
GpuPointCloud upload_point_cloud(gpu::Context& ctx, const PointCloud& cloud);
// Uploads the chunks' extras (8 bytes a point) beside a cloud that upload_point_cloud made from
// `cloud` (the same pieces, in order). Called when a filter first needs them, so the default
// path never holds them on the GPU. Chunks without extras get none (the filter then passes
// their points). Returns whether every chunk got its extras.
bool upload_point_extras(gpu::Context& ctx, GpuPointCloud& gpu_cloud, const PointCloud& cloud);

struct PointPipelines {
  WGPUTextureFormat color_format = WGPUTextureFormat_RGBA8Unorm;
  WGPUTextureFormat depth_format = WGPUTextureFormat_Depth32Float;
  gpu::BindGroupLayout frame_layout, points_layout, survivors_layout, clod_layout, resolve_layout;
  gpu::PipelineLayout direct_layout, indexed_layout, clod_pipeline_layout, resolve_pipeline_layout;
  // [0] draws every point of a chunk, [1] the CLOD survivors (indirect).
  std::array<gpu::RenderPipeline, 2> naive_out;    // opaque, into the output format
  std::array<gpu::RenderPipeline, 2> naive_hdr;    // opaque, into RGBA16Float for the resolve
  std::array<gpu::RenderPipeline, 2> splat_depth;  // depth pre-pass
  std::array<gpu::RenderPipeline, 2> splat_accum;  // additive weighted colours
  // The same four with the extras bound (group 1 binding 1), made on first use.
  gpu::BindGroupLayout points_extras_layout;
  gpu::PipelineLayout direct_extras_layout, indexed_extras_layout;
  std::array<gpu::RenderPipeline, 2> naive_out_x, naive_hdr_x, splat_depth_x, splat_accum_x;
  bool extras_pipelines = false;
  // Translucent points (points-translucent, points-composite), made on first use.
  std::array<gpu::RenderPipeline, 2> translucent, translucent_x;
  bool translucent_pipelines = false, translucent_extras_pipelines = false;
  gpu::BindGroupLayout composite_layout;
  gpu::RenderPipeline composite;
  gpu::ComputePipeline clod;
  gpu::RenderPipeline resolve;
  gpu::Buffer frame_uniforms;
  gpu::Buffer filter_uniforms;   // `Filter` of point_common.wgsl
  gpu::Buffer polygon_vertices;  // clip polygons' ring vertices, camera-relative
  gpu::Buffer chunk_uniforms;    // one slot per chunk (dynamic offsets)
  uint32_t chunk_stride = 256;
  uint32_t chunk_capacity = 0;
  gpu::BindGroup frame_group;
  gpu::TransientPool pool;  // for draw_points
  gpu::PassTimer timer;     // for draw_points: one per pass
};

PointPipelines create_point_pipelines(
    gpu::Context& ctx, WGPUTextureFormat color_format,
    WGPUTextureFormat depth_format = WGPUTextureFormat_Depth32Float);

// Names of the graph resources the passes draw into. `color` must be an imported writable
// texture of the pipelines' colour format; depth is a transient unless `create_depth` is off and
// `depth` names an imported writable texture (RenderAttachment | TextureBinding).
struct PointPassTargets {
  std::string color = "color";
  std::string depth = "depth";
  bool create_depth = true;
  // A later pass of the frame reads the depth (splats test against it): a transient depth is
  // stored even where no point pass reads it back (naive points without EDL), and can be bound
  // as a texture.
  bool keep_depth = false;
};

// Adds all passes of a frame for one cloud (see the top of this file). The cloud's GPU objects
// and the pipelines must outlive the graph's execution. Settings are copied; ranges and the
// auto point size are resolved here (point_size 0 uses auto_point_size).
void add_point_cloud_passes(gpu::RenderGraph& graph, PointPipelines& pipelines,
                            GpuPointCloud& cloud, const Camera& camera,
                            const PointRenderSettings& settings, uint32_t width, uint32_t height,
                            const PointPassTargets& targets = {});

// Records and submits one frame into `color` (a texture of the pipelines' colour format with
// RenderAttachment usage), with transient depth. For tests and one-off renders.
void draw_points(gpu::Context& ctx, PointPipelines& pipelines, GpuPointCloud& cloud,
                 const Camera& camera, const PointRenderSettings& settings, WGPUTexture color,
                 WGPUTextureView color_view, uint32_t width, uint32_t height);

// Names of the passes a frame with these settings adds, in order (`translucent`: for a cloud
// with translucent points, CloudAttributes::has_translucent).
std::vector<std::string> point_pass_names(const PointRenderSettings& settings,
                                          bool translucent = false);

// A point size in pixels that closes the gaps between neighbours for a surface scan seen from
// this camera: the mean spacing over the horizontal extent, projected at the target distance.
float auto_point_size(const PointCloud& cloud, const Camera& camera, uint32_t height);
float auto_point_size(const Aabb& world_bounds, uint64_t point_count, const Camera& camera,
                      uint32_t height);

// ---- CLOD reference (seed 000, eqs. 6-9), the same float arithmetic as clod.wgsl ----------
// r(p) = fract(cos(px + py + pz) * c) of the point's position in its chunk's local frame: that
// float position never changes, so r is stable across frames and camera moves (a camera-relative
// position would change with every move and make points flicker).
float clod_random(const glm::vec3& local);
// s_target = d * k (eq. 8) with d the distance to the camera; keep when r < s_native / s_target
// (eq. 9). s_native is the chunk's spacing: a plain LAS file has no hierarchy, so every point is
// at depth 0 of eq. 7 with s_base the chunk's mean spacing from its density.
bool clod_keep(const glm::vec3& local, const glm::vec3& chunk_offset, float spacing, float k);
// Survivors of the whole cloud for this camera, on the CPU (chunk offsets as the GPU gets them).
uint64_t clod_survivors_cpu(const PointCloud& cloud, const Camera& camera, float k);
// Survivors of the last executed CLOD pass, read back from the indirect arguments (blocks).
uint64_t read_clod_survivors(gpu::Context& ctx, const GpuPointCloud& cloud);

}  // namespace stipple::pc
