#pragma once
// 3D Gaussian splats on the GPU (issue 46), as render-graph passes beside the point clouds':
//
//   splat-project (compute)  per splat: cull, project (EWA, the reference rasterizer's rules),
//                            SH colour for the view direction, depth key; visible ones are
//                            appended and counted in the indirect draw arguments
//   splat-sort (compute)     the depth keys sorted on the GPU (radix_sort.hpp), farthest first
//   splat-draw (render)      instanced quads, back to front, premultiplied alpha, into the
//                            frame's colour target, depth-tested (not written) against the
//                            frame's depth so that splats and points occlude each other
//
// The reference's rules (Kerbl et al. 2023 and its CUDA rasterizer): covariance R S S^T R^T,
// the perspective's Jacobian at the centre clamped to 1.3 x tan(fov / 2), 0.3 px added to the
// 2D covariance, a 3-sigma radius, alpha = min(0.99, opacity * exp(power)), alpha < 1/255 not
// drawn. Camera-relative: the set's centre minus the camera in double, cast to float.
#include <cstdint>
#include <map>
#include <memory>
#include <string>
#include <unordered_map>
#include <vector>

#include "stipple/io/splats.hpp"
#include "stipple/math/camera.hpp"
#include "stipple/renderer/gpu.hpp"
#include "stipple/renderer/gpu_timer.hpp"
#include "stipple/renderer/render_graph.hpp"
#include "stipple/splats/radix_sort.hpp"

namespace stipple::splats {

// Quads: sorted instanced quads blended by the fixed-function blender. Tiles: the reference's
// 16x16 tiles in compute (each tile's splats in depth order through a second, stable sort by
// tile), blended front to back in f32 with early termination, then laid over the frame. The
// plugin, render, view and the web page draw with the device's faster one unless told
// (default_splat_rasterizer: tiles on a GPU, quads on a CPU adapter).
enum class SplatRasterizer { Quads, Tiles };
SplatRasterizer parse_splat_rasterizer(const std::string& name);
const char* splat_rasterizer_name(SplatRasterizer rasterizer);
// The faster of the two on this device (what the plugin draws with unless told): see the figures
// in splats.cpp.
SplatRasterizer default_splat_rasterizer(const gpu::Context& ctx);

// The tile rasterizer's per-set buffers (made on its first frame, remade when the size changes
// or a frame wanted more (tile, splat) pairs than they hold).
struct TileBuffers {
  uint32_t width = 0, height = 0, tiles_x = 0, tiles_y = 0;
  // (tile, splat) pairs a frame holds: at first 4 a splat, then 1.5 times the most a frame
  // wanted (TilePairCounts), up to the device's binding limit. A frame that wants more keeps
  // the nearest splats' pairs.
  uint32_t pair_capacity = 0;
  gpu::Buffer scan, tile_data, pixels, params;
  RadixSortBuffers sort;  // pairs by tile
  gpu::BindGroup binning, composite;
};

// The pairs each tile frame wanted, read back without waiting: the binning pass copies its
// total into a free slot of a small ring of mappable buffers, mapped once the frame is submitted
// and read a frame or more later (settle_tile_pairs), as gpu::PassTimerRing reads times.
struct PairSlotState {
  enum class Phase { Free, Copied, Mapping, Mapped, Failed };
  Phase phase = Phase::Free;
  std::string message;
};
struct TilePairCounts {
  struct Slot {
    gpu::Buffer readback;                  // 4 bytes, MapRead | CopyDst
    std::shared_ptr<PairSlotState> state;  // shared with the map callback (gpu::map_async)
    uint32_t capacity = 0;                 // the frame's pair capacity
  };
  std::vector<Slot> slots;
  uint32_t needed = 0;             // the most pairs a frame wanted over its capacity
  uint32_t most = 0;               // the most pairs a frame wanted (every frame read back)
  uint64_t overflowed_frames = 0;  // frames that wanted more pairs than they held
  bool warned = false;             // past the device's limit (said once)
  uint32_t max_capacity = 0;       // a limit below the device's (0: none; tests lower it)
};

// One splat set on the GPU, with the buffers its frames use (sized for every splat visible).
struct GpuSplats {
  uint32_t count = 0;
  uint32_t capacity = 0;  // splats the buffers have room for (a composed set keeps some spare)
  int sh_degree = 0;
  uint32_t sh_stride = 0;  // u32 words of SH a splat (f16 pairs)
  glm::dvec3 centre{0.0};  // the local origin of the uploaded positions, in world space
  glm::dmat3 linear{1.0};  // the set's transform without its translation
  gpu::Buffer splats, sh;
  // Per frame: the projected splats, the indirect draw arguments (whose instance count is the
  // visible count the sort reads) and the sort's buffers.
  gpu::Buffer projected, args, frame_uniforms;
  RadixSortBuffers sort;
  gpu::BindGroup project_group, draw_group;  // made on first draw
  uint64_t pipelines_id = 0;  // the SplatPipelines its groups were made for (their layouts)
  std::unique_ptr<TileBuffers> tiles;  // SplatRasterizer::Tiles
  TilePairCounts pair_counts;          // SplatRasterizer::Tiles
};

// Uploads a set (positions relative to its centre, rotations, scales and SH as f16). Throws
// stipple::Error when the set is larger than one storage binding of the device allows.
GpuSplats upload_splats(gpu::Context& ctx, const io::SplatSet& set);

// The parts of composed sets uploaded so far (compose_splats): each part in buffers of its own,
// packed once and kept while something else holds the part (a streamer keeps its resident tiles'
// splats), so the GPU holds what the host holds, and the composed set on top (room for half
// again the splats drawn).
struct SplatPartCache {
  struct Part {
    std::weak_ptr<const io::SplatSet> set;
    gpu::Buffer splats, sh;
    uint32_t sh_stride = 0;
  };
  std::unordered_map<const io::SplatSet*, Part> parts;
  uint64_t packed_splats = 0;  // splats packed and uploaded, over every call (each part once)
};

// Makes `into` draw `parts` together: splat sets in one frame (each with an identity transform,
// as a streamed tileset's tiles in its root's frame), placed in the world by `transform`. Parts
// not in `cache` are packed and uploaded into buffers of their own; then one submission copies
// every part into `into`'s buffers on the GPU, in order (lower SH degrees padded with zeros; the
// set's degree never drops, so parts are not packed again when the list's highest degree does).
// `into` is kept, with its frame buffers and the tile rasterizer's pair capacity, while it has
// room; made anew otherwise, with half again the room it lacks. So a change of parts costs the new
// parts' packing and a copy on the GPU, not a pack and upload of the whole set. Throws
// stipple::Error where a part's arrays disagree or the total exceeds a storage binding.
void compose_splats(gpu::Context& ctx, SplatPartCache& cache, std::unique_ptr<GpuSplats>& into,
                    const std::vector<std::shared_ptr<const io::SplatSet>>& parts,
                    const glm::dmat4& transform);

struct SplatPipelines {
  uint64_t id = 0;  // unique a creation: a set drawn by other pipelines remakes its bind groups
  WGPUTextureFormat color_format = WGPUTextureFormat_RGBA8Unorm;
  WGPUTextureFormat depth_format = WGPUTextureFormat_Depth32Float;
  gpu::ComputePipeline project;
  gpu::BindGroupLayout draw_layout;
  gpu::PipelineLayout draw_pipeline_layout;
  gpu::RenderPipeline draw, draw_no_depth;
  RadixSortPipelines sort;
  // SplatRasterizer::Tiles, made on first use.
  bool tile_pipelines = false;
  gpu::BindGroupLayout tile_layout;
  gpu::PipelineLayout tile_pipeline_layout;
  gpu::ComputePipeline tile_block_sums, tile_scan_blocks, tile_block_apply, tile_emit,
      tile_clear_ranges, tile_ranges, tile_raster;
  gpu::RenderPipeline tile_composite;
  gpu::Texture no_depth;  // 1x1, bound when there is no depth to test against
  gpu::TextureView no_depth_view;
  gpu::TransientPool pool;  // for draw_splats
  gpu::PassTimer timer;     // for draw_splats
};
SplatPipelines create_splat_pipelines(
    gpu::Context& ctx, WGPUTextureFormat color_format,
    WGPUTextureFormat depth_format = WGPUTextureFormat_Depth32Float);

// The graph resources the passes use. `color` must exist (imported, or written by an earlier
// pass); `depth` (the points' depth, reverse Z) is read when not empty: it must then hold the
// frame's depth when the draw runs (pointcloud's PointPassTargets::keep_depth keeps a
// transient one stored).
struct SplatPassTargets {
  std::string color = "color";
  std::string depth = "depth";  // empty: no depth test
  std::string name = "splat";   // prefix of the passes' and resources' names (one per set)
  SplatRasterizer rasterizer = SplatRasterizer::Quads;
};

// Adds the three passes (see the top of this file) for one set; with the tile rasterizer the
// draw is four: splat-bin (tiles per splat, their prefix sum, the (tile, splat) pairs),
// splat-tile-sort, splat-raster (tile ranges, blending per tile) and splat-composite. The
// depth, when tested, must then also be bindable as a texture (TextureBinding). The set and
// pipelines must outlive the graph's execution.
void add_splat_passes(gpu::RenderGraph& graph, SplatPipelines& pipelines, GpuSplats& splats,
                      const Camera& camera, uint32_t width, uint32_t height,
                      const SplatPassTargets& targets = {});

// Records and submits one frame of the set alone over `color` (kept, not cleared) and, when
// given, depth-tested against `depth` (a Depth32Float view, kept). For tests and benchmarks:
// returns the passes' GPU milliseconds from timestamp queries (waits for the frame), empty
// where the adapter has none or `timed` is off. With the tile rasterizer the frame is whole: one
// that wanted more pairs than the buffers held is drawn again once they have grown (waiting for
// its pair count; settle_tile_pairs).
std::map<std::string, double> draw_splats(gpu::Context& ctx, SplatPipelines& pipelines,
                                          GpuSplats& splats, const Camera& camera,
                                          WGPUTexture color, WGPUTextureView color_view,
                                          uint32_t width, uint32_t height,
                                          WGPUTexture depth = nullptr,
                                          WGPUTextureView depth_view = nullptr, bool timed = false,
                                          SplatRasterizer rasterizer = SplatRasterizer::Quads);

// Visible splats of the last executed frame (the draw's instance count; blocks).
uint32_t read_visible_count(gpu::Context& ctx, const GpuSplats& splats);

// Takes in the pair totals of the tile frames submitted so far that have come back (with
// `wait`, every one is waited for first; without, nothing blocks). Returns whether one of them
// wanted more pairs than its buffers held and the capacity has grown since (to 1.5 times that,
// made by the next frame's binning pass), so that drawing the frame again draws every splat.
// Past the device's limit the capacity stops there (a warning says so once) and this returns
// false. Call it only between frames (every frame it reads was submitted).
bool settle_tile_pairs(gpu::Context& ctx, GpuSplats& splats, bool wait);

// The tile rasterizer's pair capacity (0 before its first frame); for tests and statistics.
uint32_t tile_pair_capacity(const GpuSplats& splats);

}  // namespace stipple::splats
