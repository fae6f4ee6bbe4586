#pragma once
// The compute rasterizer (seed 001; WebGPU pipeline of seed 003, chapter 4): batches of points
// in compute workgroups, adaptive coordinate precision, a visibility buffer resolved with 64-bit
// atomicMin where wgpu-native has ShaderInt64AtomicMinMax, else the 32-bit two-pass fallback
// (depth atomicMin, colour atomicAdd within a depth tolerance), optional high-quality shading.
//
// Passes on the render graph: raster-clear, raster-depth (the geometry pass), then
// raster-accumulate (HQS or fallback) or raster-resolve (64-bit), and raster-display into the
// imported colour target: a compute pass through a storage binding where the target allows it
// (RGBA8Unorm with storage usage), else a full-screen render pass (any colour format).
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

// How the batch passes run (seed 001, sections 3.2-3.6); `bench raster` measures each choice.
// A kernel choice that can depend on the adapter: Auto lets the pipeline decide.
enum class AutoSwitch : uint8_t { Auto, On, Off };

struct RasterKernel {
  uint32_t workgroup = 128;  // threads per batch workgroup (the seed's 128)
  // The accumulation pass's (HQS, the 32-bit fallback's second pass); 0: `workgroup`. 256:
  // HQS 1.35x and the fallback 1.23x faster than 128 on the H200, 64 2x slower (runs L-N).
  uint32_t hqs_workgroup = 256;
  // Four points per thread and iteration from one 128-bit load (3.4), drawn written out: 1.45x
  // faster than one point a thread on the H200 (bench/RESULTS.md, run K). The earlier form, its
  // four positions in a loop-indexed array, was 2-3.6x slower there.
  bool prefetch = true;
  // With prefetch (either pass): 16-byte words a thread loads before drawing them, 1 or 2 (two
  // 128-bit loads in flight, for a loop bound by load latency).
  uint32_t prefetch_words = 1;
  bool contiguous = false;  // with prefetch: each thread one range of its batch, not a stride
  bool merge = false;       // a thread's points in a row on one pixel: one write for them
  bool plain_early = true;  // the early depth test as a plain load, as in Listing 1
  // Batches that cover at most 512 pixels are rasterized in workgroup memory first, then
  // written once per pixel (compute_raster_tile.wgsl).
  bool tile = false;
  // HQS: two packed 32-bit atomics a point instead of four (3.6); with merged sums the four
  // plain ones were 12-17 % faster on the H200.
  bool packed_hqs = false;
  // The HQS accumulation's (and the 32-bit fallback's second pass's) own choices: merging pays
  // there (the sums of a run go out in one atomic each), while in the depth passes it costs more
  // than it saves. Prefetched sums: HQS 1.6x faster than one point a thread on the H200 (run
  // K); in workgroups of 256, strided words beat contiguous ranges by 1-7 % (run N).
  bool hqs_prefetch = true;
  bool hqs_contiguous = false;
  bool hqs_merge = true;
  // The HQS sums in workgroup memory first (as `tile`, without the second phase): 1.8x faster
  // HQS at overview distances on the H200, 4 % slower close up. The geometry tile above was
  // slower there (2x: its second phase doubles the per-point work, which bounds the pass).
  bool hqs_tile = true;
  // The 64-bit depth pass's points of a subgroup on one pixel write once, their nearest key
  // found with subgroup operations (compute_raster_reduce_subgroups.wgsl). Needs the device's
  // subgroups feature (has_subgroups); without it, or with merge, the pass writes per point.
  // Off: 37 % slower on the H200, where the atomics it saves cost 1 % (bench/RESULTS.md, run J).
  bool subgroup_reduce = false;
  // Positions and pixels without int/float conversion instructions (compute_raster_batch.wgsl;
  // the image differs only at pixel edges), and batches inside the viewport without the
  // per-point clipping tests. Measured, not defaults: on the H200 0.8 % faster and 1.1 % slower
  // (run Q), so neither conversions nor clipping bound the depth pass.
  bool fast_convert = false;
  bool unclipped = false;
  // HQS sums (and the fallback's colours) in the RGB mode from the colour's bytes, not shaded
  // through floats: the same sums, HQS 1.13x faster on the H200 (bench/RESULTS.md, run Q).
  bool hqs_raw_rgb = true;
  // The depth passes' lean loop for 10-bit batches without filters (compute_raster_write.wgsl):
  // no precision, filter or per-point range branches, and no clipping tests in batches inside
  // the view. The pass issued about 100 instructions a point (the driver's SASS), the lean loop
  // about 50: 1.67x faster on the H200 (bench/RESULTS.md, runs U-Y).
  bool lean = true;
  // The accumulation pass's lean loop (HQS sums, the fallback's colours) for 10-bit batches in
  // the RGB mode without filters (compute_raster_accumulate.wgsl): the depth passes' lean
  // projection, a word's depth limits and then its colours read together. Off until measured
  // on the H200 (a lean accumulation that inlined its whole point path there grew the pass
  // 4.3x and made HQS 1.55x slower: bench/RESULTS.md, run Z).
  bool lean_sums = false;
  // The batch passes compiled without naga's bounds checks (gpu::create_shader's `trusted`;
  // wgpu-native): their indices are in range by construction (batch ranges checked on upload,
  // pixels clipped to the viewport, tile entries bounded). 1.06x faster depth pass, 1.23x
  // faster HQS accumulation on the H200.
  bool trusted = true;
  // The depth passes' early depth test (a plain read of the pixel's depth before the atomic).
  // group_early: in the lean loop a word's four early-test reads issued together before its
  // tests (compute_raster_write.wgsl): in the H200's code the driver's range check before each
  // read puts it behind a branch, so a thread waits for the four one after the other, and the
  // early test costs 30 % of the pass (bench/RESULTS.md, run Y). Off until measured there.
  bool early_test = true;
  bool group_early = false;
  // The 64-bit pass's early test on the whole key, read with a 64-bit atomic load through the
  // binding the atomicMin writes (compute_raster64_early_key.wgsl; devices with
  // ShaderInt64AtomicAllOps, else the depth word as before): the test and the atomic share an
  // address and a range check instead of two bindings' each. Off until measured on the H200.
  bool early_key = false;
  // The 32-bit fallback without its colour pass (plain frames; HQS keeps it): the depth pass
  // appends an event (pixel, depth, point index) for each point its atomicMin found no nearer
  // than itself (compute_raster_depth32_events_pass.wgsl), raster-events keeps the events at each
  // pixel's final depth, lowest index first, as the 64-bit key does (compute_raster_events.wgsl),
  // and the 64-bit path's resolve pass colours them. The event list holds events_per_pixel
  // events a pixel of the frame; when it overflows, the colour pass runs as before. Needs 9
  // storage buffers a stage (else off). Auto: on except on CPU adapters. On the H200 the
  // fallback's frame 2.2x faster (run AA: 1.73 events a pixel at the overview); on lavapipe
  // 1.24x slower (a thread there waits long for an atomic's answer: the depth pass 2.5x).
  AutoSwitch fallback_events = AutoSwitch::Auto;
  // The fallback's colour pass (without HQS) with the lean loop of lean_sums: 1.39x faster on
  // the H200 (run AA), where HQS's sums with it were 1.17x slower at the overview.
  bool lean_colours = true;
  uint32_t events_per_pixel = 4;
  // Off: every point that passes the early test appends an event, not only those the atomicMin
  // found no nearer than themselves (no thread waits for the atomic's answer; more events).
  bool events_on_win = true;
  // Every thread of a batch's workgroup classifies the batch and makes its screen matrix
  // itself, instead of thread 0 for all behind a barrier: 3.5 % slower on the H200 (the barrier
  // costs less than the instructions it saves).
  bool parallel_prologue = false;
  // The depth passes (without `tile`; needs parallel_prologue): batches a workgroup draws, a
  // grid stride apart (fewer workgroups to start and end): 2-17 % slower for 2-16.
  uint32_t batches_per_group = 1;
  // A measurement only (wrong counters): the depth passes without the batch counters' atomics.
  bool ablate_count = false;
  // A measurement only (wrong images): 1 leaves the 64-bit depth pass's atomics out, 2 also its
  // early depth tests (bench raster's no-atomic and no-write variants).
  uint32_t ablate = 0;
  // A measurement only (wrong images): positions made from the point's index instead of loaded
  // (bench raster's no-load variant).
  bool ablate_load = false;
  // A measurement only (wrong images): the accumulation pass's sums are not added (no-sums).
  bool ablate_sums = false;
};

// Whether this context can run the 64-bit visibility buffer (STIPPLE_RASTER_FALLBACK=1 says no).
bool has_visibility64(const gpu::Context& ctx);
// Whether the device has subgroup operations (RasterKernel::subgroup_reduce).
bool has_subgroups(const gpu::Context& ctx);
// Features to request for it (pass to gpu::ContextOptions::optional_features).
std::vector<WGPUFeatureName> compute_raster_features();

struct ComputeRasterPipeline {
  bool visibility64 = false;
  RasterKernel kernel;
  WGPUTextureFormat color_format = WGPUTextureFormat_RGBA8Unorm;
  gpu::ComputePipeline clear, raster64, depth32, accumulate, resolve, hqs_finish;
  // The clear without the accumulation buffer (the resolve pass writes all of it).
  gpu::ComputePipeline clear_depth;
  gpu::ComputePipeline accumulate_plain;  // the fallback's colours without HQS, where it differs
  // RasterKernel::fallback_events: its depth pass, raster-events' three entry points and the
  // colour pass that runs only when the events overflowed (an indirect dispatch that raster-events
  // sizes; with `resolve`).
  gpu::ComputePipeline depth32_events, events_overflow, events_init, events_scan,
      accumulate_overflow;
  gpu::Buffer events_dispatch;  // the colour pass's indirect dispatch sizes, a segment each
  gpu::BindGroupLayout events_layout;
  gpu::PipelineLayout events_pipeline_layout;
  // The 32-bit depth passes read the early test's depth through a plain binding (wgpu-native).
  bool depth32_plain_early = false;
  uint64_t max_storage_binding = 0;  // the device's maxStorageBufferBindingSize (the event list)
  gpu::RenderPipeline display;
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
  gpu::ComputePipeline dilate;
  gpu::Buffer dilate_params;
  // Filters and clip region (point_filter.wgsl), rewritten each frame.
  gpu::Buffer filter_uniforms, polygon_vertices;
};

struct ComputeRasterOptions {
  bool hqs = false;             // high-quality shading (seed 001, section 3.6)
  float hqs_tolerance = 0.01f;  // relative depth range that is averaged
  int force_bits = 0;           // debug: 10, 20 or 30 for every batch
  float min_batch_px = 0.0f;    // LOD: skip batches smaller than this on screen
  glm::vec3 background{0.07f, 0.08f, 0.1f};
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
};

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
