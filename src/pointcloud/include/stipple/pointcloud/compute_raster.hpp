#pragma once
// The compute rasterizer (seed 001; WebGPU pipeline of seed 003, chapter 4): batches of points
// in compute workgroups, adaptive coordinate precision, a visibility buffer resolved with 64-bit
// atomicMin where wgpu-native has ShaderInt64AtomicMinMax, else the 32-bit fallback (depth
// atomicMin, then the nearest points' colours), optional high-quality shading.
//
// Passes on the render graph:
//  - raster-clear: the depth (or visibility) buffer, and the colour sums where a pass adds to
//    them.
//  - raster-depth, the geometry pass: one workgroup a batch culls it against the frustum and
//    picks its precision from its size on screen (10, 20 or 30 bits a coordinate: only those
//    words are read); its threads load four points with one 128-bit load and keep each pixel's
//    nearest with an early depth test (a plain load where the backend allows an aliased
//    binding, else an atomic one) and an atomicMin: of (depth, point index) on the 64-bit
//    buffer, of the depth alone in the fallback. 10-bit batches without filters take a lean
//    loop written for the fewest instructions a point.
//  - 64-bit, or the fallback with winner events: raster-resolve colours each pixel's nearest
//    point. The fallback's events are the points that lowered or tied their pixel's depth, and
//    raster-events first picks each pixel's nearest of them (depth, then index).
//  - raster-accumulate: with HQS, every point within a depth tolerance of the pixel's nearest
//    adds its colour (summed in a workgroup tile for batches that cover few pixels); in the
//    fallback without events (CPU adapters, or an event list that overflowed), the nearest
//    points add theirs.
//  - raster-dilate, raster-occlusion and raster-fill where asked, then raster-display into the
//    imported colour target: a compute pass through a storage binding where the target allows
//    it (RGBA8Unorm with storage usage), else a full-screen render pass (any colour format).
//  - Clouds with translucent points in the RGB mode (ComputeRasterOptions::translucent): the
//    batch passes above skip the points whose coarse word carries kTranslucentBit (pipelines
//    made with the override SPLIT, so the default ones are unchanged), raster-translucent
//    (before the display) adds each translucent point in front of the opaque depth to
//    fixed-point sums (weighted blended order-independent transparency), and the display lays
//    their average colour over the opaque image by their coverage; EDL shades the opaque points.
// bench/RESULTS.md holds the measurements behind each choice (issue 15), and the variants that
// measured slower, retired from the code.
#include <algorithm>
#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

#include <glm/vec3.hpp>
#include <glm/vec4.hpp>

#include "stipple/math/camera.hpp"
#include "stipple/pointcloud/batches.hpp"
#include "stipple/pointcloud/filters.hpp"
#include "stipple/pointcloud/sky.hpp"
#include "stipple/renderer/gpu.hpp"
#include "stipple/renderer/render_graph.hpp"

namespace stipple::pc {

// Batched points on the GPU. Clouds larger than one storage binding (or with more batches than
// one dispatch allows) are split at batch boundaries into segments, each with its own buffers
// and dispatches; point indices in the visibility buffer are global (segment base + local).
// Within a segment the batches are in order of their first index (the resolve finds a point's
// batch by binary search).
// Bytes of one entry of a segment's batch table (GpuBatch in the shaders).
constexpr uint64_t kGpuBatchBytes = 32;

struct GpuBatchedCloud {
  struct Segment {
    gpu::Buffer coarse, medium, fine, color, attributes;
    gpu::Buffer batches;  // GpuBatch per batch, rewritten each frame (camera-relative offsets)
    gpu::Buffer params;   // uniforms, rewritten each frame
    uint32_t first_batch = 0, batch_count = 0;
    uint64_t first_point = 0;
    uint32_t point_count = 0;
  };
  std::vector<Segment> segments;
  std::vector<Batch> batches;  // CPU copy: double boxes for the per-frame offsets
  gpu::Buffer shading;         // the colour mode's uniforms, rewritten each frame
  uint64_t point_count = 0;
  uint64_t bytes = 0;  // GPU memory of the point and batch buffers
};

struct UploadOptions {
  uint64_t max_segment_points = 0;  // 0: from the device limits (tests force small segments)
};
// Copies the words to the GPU through mapped staging slots filled on every core
// (gpu::upload_through_staging).
GpuBatchedCloud upload_batched_cloud(gpu::Context& ctx, const BatchedCloud& cloud,
                                     const UploadOptions& options = {});
// A loaded cloud batched and uploaded as upload_batched_cloud(build_batches(cloud)) does, a group
// of chunks (about `group_points` points) at a time, so that the host holds one group's words
// and curve order beside the chunks (about 30 bytes a point of the group), not the cloud's (28
// bytes a point of the cloud): the page, whose memory is wasm32's 4 GB, holds seed 003's 136M
// points as one cloud this way. Batches stay within a group (a group is millions of points:
// batches as tight as the whole cloud's). Clouds under two groups, or over one storage binding,
// take the whole build as before.
GpuBatchedCloud upload_batched_chunks(gpu::Context& ctx, const PointCloud& cloud,
                                      uint64_t group_points = uint64_t(1) << 24);
// Bytes of GPU memory a point takes in the rasterizer's arrays (coarse, medium, fine, colour,
// attributes).
constexpr uint64_t kRasterPointBytes = 20;

// Empty buffers for up to `points` points and `batches` batches in one segment (each array one
// storage binding), written on the GPU by their owner: the virtual memory system's compaction
// fills the arrays and sets the batches, the segment's counts and point_count.
GpuBatchedCloud create_batched_storage(gpu::Context& ctx, uint64_t points, uint64_t batches,
                                       std::string_view label);

// GPU bytes of one array of `points` words: padded to 16 bytes, since the passes read four
// points' words at a time.
inline uint64_t raster_array_bytes(uint64_t points) {
  return std::max<uint64_t>((points * 4 + 15) & ~uint64_t(15), 16);
}

// A choice that can depend on the adapter: Auto lets the pipeline decide.
enum class AutoSwitch : uint8_t { Auto, On, Off };

// Measurements only (`stipple bench raster`'s no-* variants): parts of the batch passes left out
// to see what they cost (ABLATE_* in compute_raster_common.wgsl). Every one draws a wrong image
// (or wrong counters).
enum RasterAblation : uint32_t {
  kAblateAtomic = 1u << 0,  // the 64-bit depth pass without its atomicMin
  kAblateWrite = 1u << 1,   // the 64-bit depth pass without its early test and atomicMin
  kAblateEarly = 1u << 2,   // the depth passes without the early test: every point's atomic
  kAblateLoad = 1u << 3,    // positions made from the point's index instead of loaded
  kAblateSums = 1u << 4,    // the accumulation's sums made but not added
  kAblateCount = 1u << 5,   // the batch counters' atomics left out
};

// The rasterizer's choices that depend on the device or that tests force.
struct RasterKernel {
  // The 32-bit fallback without its colour pass (plain frames; HQS keeps it): the depth pass
  // appends an event (pixel, depth, point index) for each point its atomicMin found no nearer
  // than itself (compute_raster_depth32_events_pass.wgsl), raster-events keeps the events at each
  // pixel's final depth, lowest index first, as the 64-bit key does (compute_raster_events.wgsl),
  // and the 64-bit path's resolve pass colours them. The event list holds events_per_pixel
  // events a pixel of the frame; when it overflows, the colour pass runs as before. Needs 9
  // storage buffers a stage (else off). Auto: on except on CPU adapters. On the H200 the
  // fallback's frame 2.2x faster (bench/RESULTS.md, run AA: 1.73 events a pixel at the
  // overview); on lavapipe 1.24x slower (a thread there waits long for an atomic's answer).
  AutoSwitch fallback_events = AutoSwitch::Auto;
  uint32_t events_per_pixel = 4;
  // The batch passes shaped for CPU adapters: no barrier or workgroup memory (each thread
  // classifies its batch), HQS through the lean loop without the workgroup tile, 32 threads a
  // workgroup in the accumulation, the colour sums cleared by clearBuffer, and with the scatter
  // dilation the display reading through its winners (no resolve pass). The same images.
  // Auto: on CPU adapters (on SwiftShader the depth pass 1.5x, HQS 4-5x faster: RESULTS.md);
  // STIPPLE_RASTER_CPU_SHAPE=on|off overrides for benches.
  AutoSwitch cpu_shape = AutoSwitch::Auto;
  // RasterAblation bits: bench only, wrong images. 0 everywhere else.
  uint32_t ablate = 0;
};

// Whether this context can run the 64-bit visibility buffer (STIPPLE_RASTER_FALLBACK=1 says no):
// as u64 (wgpu-native's ShaderInt64AtomicMinMax) or as atomic<vec2u> (atomic-vec2u-min-max:
// browsers on GPUs with 64-bit atomics).
bool has_visibility64(const gpu::Context& ctx);
// Features to request for it (pass to gpu::ContextOptions::optional_features).
std::vector<WGPUFeatureName> compute_raster_features();

struct ComputeRasterPipeline {
  bool visibility64 = false;
  // The 64-bit pass through atomic<vec2u> (compute_raster_vec2u.wgsl: its early depth test reads
  // a depth buffer of its own, "raster-depth-hint").
  bool visibility_vec2u = false;
  RasterKernel kernel;
  WGPUTextureFormat color_format = WGPUTextureFormat_RGBA8Unorm;
  // The depth pass (64-bit, or the fallback's) and HQS's sums.
  gpu::ComputePipeline clear, raster64, depth32, accumulate, resolve;
  // The clear without the accumulation buffer (the resolve pass writes all of it).
  gpu::ComputePipeline clear_depth;
  // The fallback's colours without HQS: the nearest points' (without events, or where they
  // overflowed).
  gpu::ComputePipeline accumulate_colours;
  // RasterKernel::fallback_events: its depth pass and raster-events' three entry points (with
  // `resolve`); accumulate_colours runs only when the events overflowed (an indirect dispatch
  // that raster-events sizes).
  gpu::ComputePipeline depth32_events, events_overflow, events_init, events_scan;
  gpu::Buffer events_dispatch;  // the colour pass's indirect dispatch sizes, a segment each
  gpu::BindGroupLayout events_layout;
  gpu::PipelineLayout events_pipeline_layout;
  // The 32-bit depth passes read the early test's depth through a plain binding (wgpu-native);
  // Dawn refuses the aliasing, so there it is an atomic load.
  bool depth32_plain_early = false;
  uint64_t max_storage_binding = 0;  // the device's maxStorageBufferBindingSize (the event list)
  gpu::RenderPipeline display;
  // ComputeRasterOptions::depth_texture's pass, made on first use (and its form reading the
  // dilation's winners, with display_winner).
  gpu::RenderPipeline depth_export, depth_export_winner;
  // The display as a compute pass (RGBA8Unorm targets with storage usage); null otherwise.
  gpu::ComputePipeline display_compute;
  gpu::Buffer counters;  // RasterCounters as u32s, cleared each frame
  // Hole filling and the occlusion check (seed 002, III-D): one layout, two entry points.
  gpu::BindGroupLayout fill_layout;
  gpu::PipelineLayout fill_pipeline_layout;
  gpu::ComputePipeline occlusion, fill;
  gpu::Buffer occlusion_params, fill_params;
  // Points larger than one pixel: depth-aware dilation (its layout adds the output depth).
  gpu::BindGroupLayout dilate_layout;
  gpu::PipelineLayout dilate_pipeline_layout;
  gpu::ComputePipeline dilate;  // by the window over every pixel (STIPPLE_DILATE=gather)
  gpu::ComputePipeline dilate_depth, dilate_offset, dilate_resolve;  // by scatter (default)
  bool dilate_gather = false;  // which of the two this device takes
  // CPU-shaped kernels with the scatter: the display reading through the dilation's winners
  // (WINNER in compute_raster_display_common.wgsl), used where the display is their only reader.
  gpu::RenderPipeline display_winner;
  gpu::ComputePipeline display_compute_winner;
  gpu::Buffer dilate_unused[2];  // the resolve's outputs' bindings when it does not run
  gpu::Buffer dilate_params;
  // Filters and clip region (point_filter.wgsl), rewritten each frame.
  gpu::Buffer filter_uniforms, polygon_vertices;
  // Frames with translucent points (ComputeRasterOptions::translucent), made on first use: the
  // batch passes without the translucent points (SPLIT 1), raster-translucent, and the display
  // that composites it.
  struct Translucent {
    bool made = false;
    gpu::ComputePipeline depth, depth_events, accumulate, accumulate_colours, translucent,
        display_compute;
    gpu::RenderPipeline display;
    gpu::Buffer params;  // raster-translucent's disc
  } split;
};

struct ComputeRasterOptions {
  bool hqs = false;             // high-quality shading (seed 001, section 3.6)
  float hqs_tolerance = 0.01f;  // relative depth range that is averaged
  int force_bits = 0;           // debug: 10, 20 or 30 for every batch
  float min_batch_px = 0.0f;    // LOD: skip batches smaller than this on screen
  glm::vec3 background{0.07f, 0.08f, 0.1f};
  SkySettings sky;  // the Nishita sky instead of the background colour, when on
  // Seed 002, III-D: empty pixels with a drawn pixel within this radius take their mean colour
  // (0: off); points a nearer neighbour within the radius sees at an angle of at most
  // occlusion_beta radians (eq. 4) are dropped first (0: off; the seed uses 0.1).
  uint32_t fill_radius = 0;
  float occlusion_beta = 0.0f;
  uint32_t occlusion_radius = 1;
  // Eye-dome lighting in the display pass, after the above (seed 000, eqs. 10-12): strength
  // (0: off) and the neighbours' distance in pixels.
  float edl_strength = 0.0f;
  float edl_radius = 1.0f;
  // Point diameter in pixels: from 2 up, every drawn pixel is dilated to a disc of it, the
  // nearest disc winning each pixel (a depth test of round splats), before occlusion and fill.
  // (Drawing the discs in the geometry pass gives the same image; measured 9 to 17 times
  // slower on an H200 at 3 and 5 px: bench/RESULTS.md.)
  float point_size = 1.0f;
  // Colour: the mode (resolved for the data: not Auto) and its ramps, as the billboard path's
  // point_color applies them (elevation in world Y, the source elevation).
  PointShading shading{ColorMode::Rgb};
  // The colour target has WGPUTextureUsage_StorageBinding: the display runs as a compute pass
  // writing it (where the pipeline has one), else as a full-screen render pass.
  bool storage_target = false;
  // Filters and clip regions (filters.hpp), as the billboard path draws them: hidden points are
  // dropped in the geometry pass, highlighted ones tinted where they are shaded. GPS-time and
  // point-source filters need the billboard path's extras and are not applied here.
  PointFilter filter;
  ClipRegion clip;
  glm::vec4 highlight{1.0f, 0.85f, 0.1f, 0.65f};
  // The cloud's batches mark translucent points (BatchingOptions::mark_translucent) and the
  // mode is RGB: they are blended over the opaque ones (translucent_frame() decides). Off, every
  // point is drawn opaque, whatever its alpha.
  bool translucent = false;
  // When set, the frame's depth is also written into a transient Depth32Float texture of this
  // name (reverse Z, as the billboard path's; RenderAttachment | TextureBinding) for later
  // passes: splats test against it.
  std::string depth_texture;
};

// Whether a frame of a cloud with `attributes` in the shading's mode blends translucent points.
inline bool translucent_frame(const CloudAttributes& attributes, const PointShading& shading) {
  return attributes.has_translucent &&
         (shading.mode == ColorMode::Rgb || shading.mode == ColorMode::Auto);
}

// Which form the display pass takes. Auto: the compute form for RGBA8Unorm targets except on
// CPU adapters, where a storage-texture write costs more than a fragment (lavapipe: 153 ms
// against 17 ms at 1280x720); STIPPLE_DISPLAY_PASS=render or =compute overrides Auto.
enum class DisplayPass { Auto, Render, Compute };

// `force_fallback` runs the 32-bit two-pass pipeline even where 64-bit atomics exist.
ComputeRasterPipeline create_compute_raster_pipeline(gpu::Context& ctx,
                                                     WGPUTextureFormat color_format,
                                                     bool force_fallback = false,
                                                     DisplayPass display = DisplayPass::Auto,
                                                     const RasterKernel& kernel = {});

// Adds the rasterizer's passes, drawing into `color_target` (an imported writable texture of
// width x height). The cloud and pipeline must outlive the graph's execution.
void add_compute_raster_passes(gpu::RenderGraph& graph, ComputeRasterPipeline& pipeline,
                               GpuBatchedCloud& cloud, const Camera& camera,
                               const ComputeRasterOptions& options, uint32_t width, uint32_t height,
                               const std::string& color_target = "color");

// The counters of the last executed frame (blocks until it is done).
RasterCounters read_raster_counters(gpu::Context& ctx, const ComputeRasterPipeline& pipeline);

}  // namespace stipple::pc
