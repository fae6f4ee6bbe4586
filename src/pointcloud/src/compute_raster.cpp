#include "stipple/pointcloud/compute_raster.hpp"

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <memory>
#include <string_view>

#include <fmt/format.h>
#include <webgpu/wgpu.h>
#include <glm/gtc/type_ptr.hpp>

#include "filter_uniforms.hpp"
#include "stipple/core/error.hpp"
#include "stipple/core/log.hpp"
#include "stipple/core/thread_pool.hpp"
#include "stipple/renderer/shader_preprocessor.hpp"
#include "stipple/renderer/staging.hpp"

namespace stipple::pc {
namespace {

// A bench switch between two forms of a pass: true where the environment variable `name` says
// `yes`, false where it says `no`, else `otherwise` (the device's choice).
bool env_choice(const char* name, std::string_view yes, std::string_view no, bool otherwise) {
  const char* env = std::getenv(name);
  const std::string_view forced = env ? env : "";
  return forced == yes ? true : forced == no ? false : otherwise;
}

// How raster-dilate runs (see its pass): the window over every pixel on GPUs, scatter from the
// drawn pixels on CPU adapters; STIPPLE_DILATE=gather|scatter overrides.
bool dilate_by_gather(const gpu::Context& ctx) {
  return env_choice("STIPPLE_DILATE", "gather", "scatter", !gpu::is_cpu_adapter(ctx.description));
}

// Mirrors Params in compute_raster_common.wgsl.
struct Params {
  float view_proj[16];
  uint32_t width, height;
  uint32_t segment_base, batch_count;
  uint32_t force_bits;
  float min_batch_px;
  float depth_tolerance;
  uint32_t depth_stride, depth_word;
  uint32_t segment_points;
  float edl_strength, edl_radius;
  float background[4];
  SkyUniforms sky;
};
static_assert(sizeof(Params) == 240);

// Mirrors GpuBatch.
struct GpuBatch {
  float offset[3];
  uint32_t count;
  float size[3];
  uint32_t first;
};
static_assert(sizeof(GpuBatch) == kGpuBatchBytes);

constexpr uint32_t kCounterWords = 13;  // see C_* in compute_raster_common.wgsl

// Mirrors Shading in compute_raster_shading.wgsl.
struct ShadingUniforms {
  uint32_t mode, needs_attributes, pad0, pad1;
  float ranges[4];
  float constant_color[4];
  float palette[32][4];
};
static_assert(sizeof(ShadingUniforms) == 560);

ShadingUniforms shading_uniforms(const PointShading& s, const Camera& camera) {
  ShadingUniforms u{};
  const ColorMode mode = s.mode == ColorMode::Auto ? ColorMode::Rgb : s.mode;
  u.mode = uint32_t(mode);
  u.needs_attributes = mode == ColorMode::Intensity || mode == ColorMode::Classification ||
                       mode == ColorMode::ReturnNumber;
  // Camera-relative Y plus this offset is the height above the ramp's minimum (double here).
  u.ranges[0] = float(camera.position.y - s.elevation_range.x);
  u.ranges[1] = float(1.0 / std::max(s.elevation_range.y - s.elevation_range.x, 1e-9));
  u.ranges[2] = float(s.intensity_range.x);
  u.ranges[3] = float(1.0 / std::max(s.intensity_range.y - s.intensity_range.x, 1e-9));
  for (int c = 0; c < 3; ++c) u.constant_color[c] = s.constant_color[c];
  u.constant_color[3] = 1.0f;
  const auto& palette = classification_palette();
  for (size_t i = 0; i < palette.size(); ++i) {
    for (int c = 0; c < 3; ++c) u.palette[i][c] = palette[i][c];
    u.palette[i][3] = 1.0f;
  }
  return u;
}

// One workgroup per batch, in rows of at most 65,535 (WebGPU's guaranteed dimension limit).
constexpr uint32_t kDispatchRow = 65'535;
constexpr size_t kFrameTablePiece = 16'384;  // batches made camera-relative a piece

void dispatch_batches(WGPUComputePassEncoder pass, WGPUComputePipeline pipeline,
                      WGPUBindGroup group, uint32_t batches) {
  if (batches == 0) return;
  const uint32_t x = std::min(batches, kDispatchRow),
                 y = (batches + kDispatchRow - 1) / kDispatchRow;
  gpu::dispatch(pass, pipeline, {group}, x, y);
}

// The accumulation pass's bindings for one segment: its points, the depth buffer and the sums.
gpu::BindGroup accumulate_bind_group(gpu::Context& ctx, WGPUBindGroupLayout layout,
                                     const GpuBatchedCloud::Segment& seg,
                                     const GpuBatchedCloud& cloud, const ComputeRasterPipeline& p,
                                     WGPUBuffer depth, WGPUBuffer sums) {
  return gpu::create_bind_group(
      ctx, layout,
      {gpu::bind_buffer(0, seg.params.get()), gpu::bind_buffer(1, seg.batches.get()),
       gpu::bind_buffer(2, seg.coarse.get()), gpu::bind_buffer(3, seg.medium.get()),
       gpu::bind_buffer(4, seg.fine.get()), gpu::bind_buffer(5, seg.color.get()),
       gpu::bind_buffer(6, depth), gpu::bind_buffer(7, sums),
       gpu::bind_buffer(9, seg.attributes.get()), gpu::bind_buffer(10, cloud.shading.get()),
       gpu::bind_buffer(11, p.filter_uniforms.get()),
       gpu::bind_buffer(12, p.polygon_vertices.get())});
}

// The accumulation pass's bind groups, one a segment, for `pipeline`'s layout.
std::vector<gpu::BindGroup> accumulate_bind_groups(gpu::Context& ctx,
                                                   const gpu::ComputePipeline& pipeline,
                                                   const GpuBatchedCloud& cloud,
                                                   const ComputeRasterPipeline& p, WGPUBuffer depth,
                                                   WGPUBuffer sums) {
  auto layout = gpu::bind_group_layout_of(pipeline);
  std::vector<gpu::BindGroup> groups;
  for (const auto& seg : cloud.segments)
    groups.push_back(accumulate_bind_group(ctx, layout.get(), seg, cloud, p, depth, sums));
  return groups;
}

gpu::ComputePipeline make_compute(gpu::Context& ctx, const char* file,
                                  std::span<const gpu::PipelineConstant> constants = {},
                                  bool trusted = false) {
  gpu::ShaderModule shader =
      gpu::create_shader_from_file(ctx, file, gpu::default_shader_files(), {}, trusted);
  gpu::ComputePipeline pipeline =
      gpu::create_compute_pipeline(ctx, shader.get(), "main", nullptr, file, constants);
  ctx.check(file);
  return pipeline;
}

// Threads a workgroup: the seed's 128 in the depth passes; 256 in the accumulation, where HQS
// was 1.35x and the fallback's colours 1.23x faster than with 128 on the H200, and 64 2x slower
// (bench/RESULTS.md, runs L-N). CPU-shaped kernels (RasterKernel::cpu_shape) take 32 in the
// accumulation: on SwiftShader HQS 1.4x faster than with 256 (both without barriers).
constexpr uint32_t kDepthWorkgroup = 128;
constexpr uint32_t kAccumulateWorkgroup = 256;
constexpr uint32_t kCpuAccumulateWorkgroup = 32;

bool cpu_shaped(const RasterKernel& kernel) {
  return kernel.cpu_shape == AutoSwitch::On;
}

// The pipeline constants of the depth passes.
std::vector<gpu::PipelineConstant> depth_constants(const RasterKernel& kernel) {
  std::vector<gpu::PipelineConstant> constants = {{"WORKGROUP", double(kDepthWorkgroup)},
                                                  {"ABLATE", double(kernel.ablate)}};
  if (cpu_shaped(kernel)) constants.push_back({"PROLOGUE_PER_THREAD", 1.0});
  return constants;
}

// The accumulation pass's: HQS's sums go through the workgroup tile and the general loop; the
// fallback's colours (the nearest points only, few atomics) the screen's sums and the lean loop.
// CPU-shaped, both take the lean loop and the screen's sums: the tile's barriers cost more than
// its atomics save there.
std::vector<gpu::PipelineConstant> accumulate_constants(const RasterKernel& kernel, bool hqs) {
  const bool cpu = cpu_shaped(kernel);
  std::vector<gpu::PipelineConstant> constants = {
      {"WORKGROUP", double(cpu ? kCpuAccumulateWorkgroup : kAccumulateWorkgroup)},
      {"ABLATE", double(kernel.ablate)},
      {"TILE", hqs && !cpu ? 1.0 : 0.0},
      {"LEAN", hqs && !cpu ? 0.0 : 1.0}};
  if (cpu) constants.push_back({"PROLOGUE_PER_THREAD", 1.0});
  return constants;
}

// The depth pass's shader for the pipeline's variant (64-bit, or the fallback's with or without
// events, its early test plain or atomic).
const char* depth_shader(const ComputeRasterPipeline& p, bool events) {
  if (p.visibility_vec2u) return "compute_raster_vec2u.wgsl";
  if (p.visibility64) return "compute_raster64.wgsl";
  if (events)
    return p.depth32_plain_early ? "compute_raster_depth32_events_plain.wgsl"
                                 : "compute_raster_depth32_events.wgsl";
  return p.depth32_plain_early ? "compute_raster_depth32_plain.wgsl"
                               : "compute_raster_depth32.wgsl";
}

// The constants with the override SPLIT added (compute_raster_batch.wgsl).
std::vector<gpu::PipelineConstant> split(std::vector<gpu::PipelineConstant> constants,
                                         uint32_t which) {
  constants.push_back({"SPLIT", double(which)});
  return constants;
}

// raster-translucent's disc (DiscParams in compute_raster_translucent.wgsl).
struct DiscParams {
  uint32_t width, height, radius, depth_stride, depth_word;
  float pad0, pad1;
  float radius2;
};
static_assert(sizeof(DiscParams) == 32);

// The pipelines of frames with translucent points (ComputeRasterPipeline::split): made the
// first time a frame needs them, so that other clouds never compile them.
void ensure_split_pipelines(gpu::Context& ctx, ComputeRasterPipeline& p) {
  auto& t = p.split;
  if (t.made) return;
  constexpr bool trusted = true;
  t.depth = make_compute(ctx, depth_shader(p, false), split(depth_constants(p.kernel), 1), trusted);
  if (!p.visibility64 && p.kernel.fallback_events == AutoSwitch::On)
    t.depth_events =
        make_compute(ctx, depth_shader(p, true), split(depth_constants(p.kernel), 1), trusted);
  t.accumulate = make_compute(ctx, "compute_raster_accumulate.wgsl",
                              split(accumulate_constants(p.kernel, true), 1), trusted);
  if (!p.visibility64)
    t.accumulate_colours = make_compute(ctx, "compute_raster_accumulate.wgsl",
                                        split(accumulate_constants(p.kernel, false), 1), trusted);
  // The general loop only (LEAN off): translucent points are the exception, not the bulk.
  const gpu::PipelineConstant translucent[] = {
      {"WORKGROUP", double(kDepthWorkgroup)}, {"LEAN", 0.0}, {"SPLIT", 2.0}};
  t.translucent = make_compute(ctx, "compute_raster_translucent.wgsl", translucent, trusted);
  gpu::ShaderModule display =
      gpu::create_shader_from_file(ctx, "compute_raster_display_translucent.wgsl");
  t.display = gpu::create_fullscreen_pipeline(ctx, {.module = display.get(),
                                                    .vertex_entry = "vs_main",
                                                    .fragment_entry = "fs_main",
                                                    .format = p.color_format,
                                                    .label = "raster-display-translucent"});
  if (p.display_compute)
    t.display_compute = make_compute(ctx, "compute_raster_display_cs_translucent.wgsl");
  t.params =
      gpu::create_buffer(ctx, sizeof(DiscParams), WGPUBufferUsage_Uniform | WGPUBufferUsage_CopyDst,
                         "raster-translucent-params");
  ctx.check("creating the translucent raster pipelines");
  t.made = true;
}

// The most bytes one point array of a segment may take: the device's binding and buffer
// limits, kept at 2 GiB so that u32 byte offsets stay safe.
uint64_t max_array_bytes(const gpu::Context& ctx) {
  return std::min<uint64_t>(
      {ctx.limits.maxStorageBufferBindingSize, ctx.limits.maxBufferSize, 1ull << 31});
}

// A segment's batch table (room for `batches`) and uniforms; `prefix` names them
// ("raster": raster-batches, raster-params).
void create_segment_tables(gpu::Context& ctx, GpuBatchedCloud::Segment& seg, uint64_t batches,
                           std::string_view prefix) {
  seg.batches = gpu::create_buffer(ctx, batches * sizeof(GpuBatch),
                                   WGPUBufferUsage_Storage | WGPUBufferUsage_CopyDst,
                                   fmt::format("{}-batches", prefix));
  seg.params =
      gpu::create_buffer(ctx, sizeof(Params), WGPUBufferUsage_Uniform | WGPUBufferUsage_CopyDst,
                         fmt::format("{}-params", prefix));
}

gpu::Buffer create_shading_uniforms(gpu::Context& ctx, std::string_view prefix) {
  return gpu::create_buffer(ctx, sizeof(ShadingUniforms),
                            WGPUBufferUsage_Uniform | WGPUBufferUsage_CopyDst,
                            fmt::format("{}-shading", prefix));
}

}  // namespace

GpuBatchedCloud upload_batched_cloud(gpu::Context& ctx, const BatchedCloud& cloud,
                                     const UploadOptions& options) {
  GpuBatchedCloud out;
  out.batches = cloud.batches;
  out.point_count = cloud.point_count();
  // One storage binding per array: the segment's points must fit the binding and the buffer
  // limits (kept at 2 GiB so u32 byte offsets stay safe). Batches go in rows of workgroups.
  uint64_t max_points = max_array_bytes(ctx) / 4;
  if (options.max_segment_points) max_points = std::min(max_points, options.max_segment_points);
  if (out.point_count >= (1ull << 32))
    fail("the compute rasterizer indexes points with 32 bits: {} points are too many",
         out.point_count);

  std::vector<gpu::BufferUpload> uploads;
  size_t b = 0;
  while (b < cloud.batches.size()) {
    GpuBatchedCloud::Segment seg;
    seg.first_batch = uint32_t(b);
    seg.first_point = cloud.batches[b].first;
    uint64_t points = 0;
    while (b < cloud.batches.size() &&
           (points + cloud.batches[b].count <= max_points || seg.batch_count == 0)) {
      if (cloud.batches[b].first != seg.first_point + points)
        fail("batches must cover consecutive points (batch {})", b);
      points += cloud.batches[b].count;
      ++seg.batch_count;
      ++b;
    }
    if (points > max_points) fail("a batch of {} points exceeds a storage binding", points);
    seg.point_count = uint32_t(points);
    const uint64_t f = seg.first_point;
    const auto usage = WGPUBufferUsage_Storage | WGPUBufferUsage_CopyDst | WGPUBufferUsage_CopySrc;
    const std::pair<gpu::Buffer*, const PointWords*> arrays[] = {
        {&seg.coarse, &cloud.coarse},
        {&seg.medium, &cloud.medium},
        {&seg.fine, &cloud.fine},
        {&seg.color, &cloud.color},
        {&seg.attributes, &cloud.attributes}};
    for (const auto& [buffer, words] : arrays) {
      *buffer = gpu::create_buffer(ctx, raster_array_bytes(points), usage, "raster-points");
      uploads.push_back({buffer->get(), 0, words->data() + f, points * 4});
    }
    create_segment_tables(ctx, seg, seg.batch_count, "raster");
    out.bytes += points * kRasterPointBytes + uint64_t(seg.batch_count) * sizeof(GpuBatch);
    out.segments.push_back(std::move(seg));
  }
  out.shading = create_shading_uniforms(ctx, "raster");
  gpu::upload_through_staging(ctx, uploads, &batching_pool());
  ctx.check("uploading batched points");
  return out;
}

GpuBatchedCloud upload_batched_chunks(gpu::Context& ctx, const PointCloud& cloud,
                                      uint64_t group_points) {
  BatchingOptions options;
  options.mark_translucent = cloud.attributes.has_translucent;
  uint64_t total = 0;
  for (const PointChunk& c : cloud.chunks) total += c.vertices.size();
  const uint64_t max_points = max_array_bytes(ctx) / 4;
  group_points = std::max<uint64_t>(group_points, 1);
  if (total < 2 * group_points || total > max_points)
    return upload_batched_cloud(ctx, build_batches(cloud, options));

  GpuBatchedCloud out;
  out.point_count = total;
  GpuBatchedCloud::Segment seg;
  seg.point_count = uint32_t(total);
  const auto usage = WGPUBufferUsage_Storage | WGPUBufferUsage_CopyDst | WGPUBufferUsage_CopySrc;
  gpu::Buffer* arrays[] = {&seg.coarse, &seg.medium, &seg.fine, &seg.color, &seg.attributes};
  for (gpu::Buffer* b : arrays)
    *b = gpu::create_buffer(ctx, raster_array_bytes(total), usage, "raster-points");
  const std::span<const PointChunk> chunks(cloud.chunks);
  uint64_t first = 0;
  for (size_t c = 0; c < chunks.size();) {
    size_t end = c;
    uint64_t points = 0;
    while (end < chunks.size() && (points < group_points || end == c))
      points += chunks[end++].vertices.size();
    BatchedCloud part;
    append_chunk_batches(part, chunks.subspan(c, end - c), options);
    for (Batch b : part.batches) {
      b.first += first;
      out.batches.push_back(b);
    }
    const PointWords* words[] = {&part.coarse, &part.medium, &part.fine, &part.color,
                                 &part.attributes};
    std::vector<gpu::BufferUpload> uploads;
    for (size_t a = 0; a < 5; ++a)
      uploads.push_back({arrays[a]->get(), first * 4, words[a]->data(), points * 4});
    gpu::upload_through_staging(ctx, uploads, &batching_pool());
    first += points;
    c = end;
  }
  seg.batch_count = uint32_t(out.batches.size());
  create_segment_tables(ctx, seg, seg.batch_count, "raster");
  out.bytes = total * kRasterPointBytes + uint64_t(seg.batch_count) * sizeof(GpuBatch);
  out.segments.push_back(std::move(seg));
  out.shading = create_shading_uniforms(ctx, "raster");
  ctx.check("uploading batched points");
  return out;
}

std::vector<WGPUFeatureName> compute_raster_features() {
  return {WGPUFeatureName(WGPUNativeFeature_ShaderInt64),
          WGPUFeatureName(WGPUNativeFeature_ShaderInt64AtomicMinMax),
          gpu::kFeatureAtomicVec2uMinMax};
}

GpuBatchedCloud create_batched_storage(gpu::Context& ctx, uint64_t points, uint64_t batches,
                                       std::string_view label) {
  const uint64_t max_bytes = max_array_bytes(ctx);
  if (raster_array_bytes(points) > max_bytes)
    fail("{}: {} points exceed one storage binding ({} bytes)", label, points, max_bytes);
  const auto usage = WGPUBufferUsage_Storage | WGPUBufferUsage_CopySrc | WGPUBufferUsage_CopyDst;
  const uint64_t words = raster_array_bytes(points);
  GpuBatchedCloud out;
  GpuBatchedCloud::Segment seg;
  seg.coarse = gpu::create_buffer(ctx, words, usage, "store-coarse");
  seg.medium = gpu::create_buffer(ctx, words, usage, "store-medium");
  seg.fine = gpu::create_buffer(ctx, words, usage, "store-fine");
  seg.color = gpu::create_buffer(ctx, words, usage, "store-color");
  seg.attributes = gpu::create_buffer(ctx, words, usage, "store-attributes");
  create_segment_tables(ctx, seg, std::max<uint64_t>(batches, 1), "store");
  out.bytes = words * 5 + std::max<uint64_t>(batches, 1) * sizeof(GpuBatch) + sizeof(Params) +
              sizeof(ShadingUniforms);
  out.segments.push_back(std::move(seg));
  out.shading = create_shading_uniforms(ctx, "store");
  return out;
}

namespace {
// Set once a browser's compiler refused the atomic<vec2u> pass: later pipelines and reports take
// the fallback without trying again.
std::atomic<bool> vec2u_refused{false};

bool has_u64_atomics(const gpu::Context& ctx) {
  return ctx.has_feature(WGPUFeatureName(WGPUNativeFeature_ShaderInt64)) &&
         ctx.has_feature(WGPUFeatureName(WGPUNativeFeature_ShaderInt64AtomicMinMax));
}
}  // namespace

bool has_visibility64(const gpu::Context& ctx) {
  if (const char* env = std::getenv("STIPPLE_RASTER_FALLBACK"); env && *env && *env != '0')
    return false;
  return has_u64_atomics(ctx) ||
         (ctx.has_feature(gpu::kFeatureAtomicVec2uMinMax) && !vec2u_refused.load());
}

ComputeRasterPipeline create_compute_raster_pipeline(gpu::Context& ctx,
                                                     WGPUTextureFormat color_format,
                                                     bool force_fallback, DisplayPass display,
                                                     const RasterKernel& kernel) {
  ComputeRasterPipeline p;
  p.visibility64 = !force_fallback && has_visibility64(ctx);
  p.visibility_vec2u = p.visibility64 && !has_u64_atomics(ctx);
  p.color_format = color_format;
  p.kernel = kernel;
  if (p.kernel.cpu_shape == AutoSwitch::Auto)
    p.kernel.cpu_shape =
        env_choice("STIPPLE_RASTER_CPU_SHAPE", "on", "off", gpu::is_cpu_adapter(ctx.description))
            ? AutoSwitch::On
            : AutoSwitch::Off;
  p.max_storage_binding = ctx.limits.maxStorageBufferBindingSize;
  p.clear = make_compute(ctx, "compute_raster_clear.wgsl");
  const gpu::PipelineConstant depth_only[] = {{"CLEAR_ACCUM", 0.0}};
  p.clear_depth = make_compute(ctx, "compute_raster_clear.wgsl", depth_only);
  // The batch passes are compiled without naga's bounds checks (`trusted`, wgpu-native): their
  // indices are in range by construction (batch ranges checked on upload, pixels clipped to the
  // viewport, tile entries bounded). The depth pass 1.06x, HQS 1.19x faster on the H200
  // (bench/RESULTS.md, runs W-Y); STIPPLE_SHADER_CHECKS=on keeps the checks.
  constexpr bool trusted = true;
  const auto depth = depth_constants(p.kernel);
  if (p.visibility_vec2u) {
    // A browser's newer feature: should its compiler refuse the pass, the page still draws,
    // with the fallback (said once).
    try {
      p.raster64 = make_compute(ctx, depth_shader(p, false), depth, trusted);
    } catch (const Error& e) {
      STIPPLE_WARN(
          "the 64-bit depth pass (atomic<vec2u>) failed, drawing with the 32-bit "
          "fallback: {}",
          e.what());
      p.visibility64 = p.visibility_vec2u = false;
      vec2u_refused = true;
    }
  }
  if (p.visibility64) {
    if (!p.raster64) p.raster64 = make_compute(ctx, depth_shader(p, false), depth, trusted);
    p.resolve = make_compute(ctx, "compute_raster_resolve.wgsl");
  } else {
    // wgpu-native lets the early test read the depth buffer through a second, plain binding
    // (as the 64-bit pass does); Dawn refuses the aliasing, so there it is an atomic load.
    p.depth32_plain_early = ctx.description.backend == "wgpu";
    p.depth32 = make_compute(ctx, depth_shader(p, false), depth, trusted);
    // The fallback's colours: the nearest points' (the colour pass), where events are off or
    // overflowed.
    p.accumulate_colours = make_compute(ctx, "compute_raster_accumulate.wgsl",
                                        accumulate_constants(p.kernel, false), trusted);
    const bool events_wanted =
        kernel.fallback_events == AutoSwitch::On ||
        (kernel.fallback_events == AutoSwitch::Auto && ctx.description.adapter_type != "CPU");
    p.kernel.fallback_events = events_wanted && kernel.events_per_pixel > 0 &&
                                       ctx.limits.maxStorageBuffersPerShaderStage >= 9
                                   ? AutoSwitch::On
                                   : AutoSwitch::Off;
    if (p.kernel.fallback_events == AutoSwitch::On) {
      p.depth32_events = make_compute(ctx, depth_shader(p, true), depth, trusted);
      // One layout for the three entry points, which use different subsets of it.
      using B = gpu::BufferBinding;
      p.events_layout = gpu::create_compute_layout(
          ctx, {B::Uniform, B::Storage, B::ReadOnlyStorage, B::Storage, B::Storage, B::Storage},
          "raster-events");
      p.events_pipeline_layout = gpu::create_pipeline_layout(ctx, {p.events_layout.get()});
      gpu::ShaderModule events = gpu::create_shader_from_file(ctx, "compute_raster_events.wgsl");
      WGPUPipelineLayout layout = p.events_pipeline_layout.get();
      p.events_overflow = gpu::create_compute_pipeline(ctx, events.get(), "overflow_main", layout,
                                                       "raster-events-overflow");
      p.events_init = gpu::create_compute_pipeline(ctx, events.get(), "init_main", layout,
                                                   "raster-events-init");
      p.events_scan = gpu::create_compute_pipeline(ctx, events.get(), "events_main", layout,
                                                   "raster-events-scan");
      p.resolve = make_compute(ctx, "compute_raster_resolve.wgsl");
      ctx.check("creating raster-events");
    }
  }
  p.accumulate = make_compute(ctx, "compute_raster_accumulate.wgsl",
                              accumulate_constants(p.kernel, true), trusted);

  gpu::ShaderModule display_module =
      gpu::create_shader_from_file(ctx, "compute_raster_display.wgsl");
  p.display = gpu::create_fullscreen_pipeline(ctx, {.module = display_module.get(),
                                                    .vertex_entry = "vs_main",
                                                    .fragment_entry = "fs_main",
                                                    .format = color_format,
                                                    .label = "raster-display"});
  if (display == DisplayPass::Auto)
    display = env_choice("STIPPLE_DISPLAY_PASS", "render", "compute",
                         ctx.description.adapter_type == "CPU")
                  ? DisplayPass::Render
                  : DisplayPass::Compute;
  if (display == DisplayPass::Compute && color_format == WGPUTextureFormat_RGBA8Unorm)
    p.display_compute = make_compute(ctx, "compute_raster_display_cs.wgsl");
  // The display through the dilation's winners (WINNER): where the scatter dilates and the
  // kernels are CPU-shaped, as the resolve pass's full-screen copy costs most there.
  p.dilate_gather = dilate_by_gather(ctx);
  if (cpu_shaped(p.kernel) && !p.dilate_gather) {
    for (auto& b : p.dilate_unused)
      b = gpu::create_buffer(ctx, 16, WGPUBufferUsage_Storage, "raster-dilate-unused");
    const gpu::PipelineConstant winner[] = {{"WINNER", 1.0}};
    p.display_winner = gpu::create_fullscreen_pipeline(ctx, {.module = display_module.get(),
                                                             .vertex_entry = "vs_main",
                                                             .fragment_entry = "fs_main",
                                                             .format = color_format,
                                                             .label = "raster-display-winner",
                                                             .constants = winner});
    if (p.display_compute)
      p.display_compute_winner = make_compute(ctx, "compute_raster_display_cs.wgsl", winner);
  }

  {
    using B = gpu::BufferBinding;
    p.fill_layout = gpu::create_compute_layout(
        ctx, {B::Uniform, B::ReadOnlyStorage, B::ReadOnlyStorage, B::Storage}, "raster-fill");
    p.fill_pipeline_layout = gpu::create_pipeline_layout(ctx, {p.fill_layout.get()});
    gpu::ShaderModule fill = gpu::create_shader_from_file(ctx, "compute_raster_fill.wgsl");
    p.occlusion = gpu::create_compute_pipeline(ctx, fill.get(), "occlusion_main",
                                               p.fill_pipeline_layout.get(), "raster-occlusion");
    p.fill = gpu::create_compute_pipeline(ctx, fill.get(), "fill_main",
                                          p.fill_pipeline_layout.get(), "raster-fill");
    const auto uniform = WGPUBufferUsage_Uniform | WGPUBufferUsage_CopyDst;
    p.occlusion_params = gpu::create_buffer(ctx, 32, uniform, "raster-occlusion-params");
    p.fill_params = gpu::create_buffer(ctx, 32, uniform, "raster-fill-params");
    p.dilate_layout = gpu::create_compute_layout(
        ctx,
        {B::Uniform, B::ReadOnlyStorage, B::ReadOnlyStorage, B::Storage, B::Storage, B::Storage},
        "raster-dilate");
    p.dilate_pipeline_layout = gpu::create_pipeline_layout(ctx, {p.dilate_layout.get()});
    p.dilate = gpu::create_compute_pipeline(ctx, fill.get(), "dilate_main",
                                            p.dilate_pipeline_layout.get(), "raster-dilate");
    p.dilate_depth = gpu::create_compute_pipeline(ctx, fill.get(), "dilate_depth_main",
                                                  p.dilate_pipeline_layout.get(), "raster-dilate");
    p.dilate_offset = gpu::create_compute_pipeline(ctx, fill.get(), "dilate_offset_main",
                                                   p.dilate_pipeline_layout.get(), "raster-dilate");
    p.dilate_resolve = gpu::create_compute_pipeline(
        ctx, fill.get(), "dilate_resolve_main", p.dilate_pipeline_layout.get(), "raster-dilate");
    p.dilate_params = gpu::create_buffer(ctx, 32, uniform, "raster-dilate-params");
  }
  p.filter_uniforms =
      gpu::create_buffer(ctx, sizeof(detail::FilterUniforms),
                         WGPUBufferUsage_Uniform | WGPUBufferUsage_CopyDst, "raster-filter");
  p.polygon_vertices =
      gpu::create_buffer(ctx, kMaxGpuPolygonVertices * 8,
                         WGPUBufferUsage_Storage | WGPUBufferUsage_CopyDst, "raster-clip-polygons");
  p.counters = gpu::create_buffer(
      ctx, kCounterWords * 4 + 4,
      WGPUBufferUsage_Storage | WGPUBufferUsage_CopySrc | WGPUBufferUsage_CopyDst,
      "raster-counters");
  ctx.check("creating the compute rasterizer");
  STIPPLE_DEBUG("compute rasterizer: {}", p.visibility_vec2u
                                              ? "64-bit visibility buffer (atomic<vec2u>)"
                                          : p.visibility64 ? "64-bit visibility buffer"
                                                           : "32-bit two-pass fallback");
  return p;
}

void add_compute_raster_passes(gpu::RenderGraph& graph, ComputeRasterPipeline& p,
                               GpuBatchedCloud& cloud, const Camera& camera,
                               const ComputeRasterOptions& options, uint32_t width, uint32_t height,
                               const std::string& color_target) {
  const bool use64 = p.visibility64;
  // The fallback's winner events (RasterKernel::fallback_events) stand in for its colour pass.
  const bool events = !use64 && !options.hqs && p.kernel.fallback_events == AutoSwitch::On;
  const bool accumulate = options.hqs || (!use64 && !events);
  const bool large = options.point_size >= 2.0f;  // dilated after the geometry pass
  // Translucent points blended over the opaque ones: the split pipelines (made before the
  // passes run), raster-translucent and its display.
  const bool translucent = options.translucent;
  const uint64_t pixels = uint64_t(width) * height;
  const std::string depth_name = "raster-depth-buffer", accum_name = "raster-accum";
  const std::string events_name = "raster-events", visibility_name = "raster-visibility";
  const std::string hint_name = "raster-depth-hint";  // the atomic<vec2u> pass's early test
  const bool hint = p.visibility_vec2u;
  constexpr uint64_t kEventRegions = 1024;  // as in compute_raster_depth32_events_pass.wgsl
  uint64_t event_bytes = 0;
  if (events) {
    // Three words an event, the regions' counters first; within the binding limit.
    const uint64_t limit = std::min<uint64_t>(p.max_storage_binding, uint64_t(1) << 31);
    uint64_t per_region = (pixels * p.kernel.events_per_pixel + kEventRegions - 1) / kEventRegions;
    per_region = std::min(per_region, (limit / 4 - kEventRegions) / (3 * kEventRegions));
    event_bytes = (kEventRegions + kEventRegions * 3 * per_region) * 4;
  }
  const uint32_t groups_x = (width + 15) / 16, groups_y = (height + 15) / 16;

  // The filter's uniforms are made now, so that a region past the GPU's limits is an error here
  // rather than in the pass.
  auto filter = std::make_shared<detail::FilterUniforms>();
  auto polygons = std::make_shared<std::vector<float>>(detail::make_filter_uniforms(
      options.filter, options.clip, options.highlight, camera, *filter));
  // Per-frame uniforms and camera-relative batch tables (double subtraction, then float).
  auto upload_frame = [&cloud, &p, camera, options, width, height, use64, filter,
                       polygons](gpu::Context& ctx) {
    gpu::write_buffer(ctx, p.filter_uniforms.get(), 0, *filter);
    if (!polygons->empty())
      gpu::write_buffer(ctx, p.polygon_vertices.get(), 0, polygons->data(),
                        polygons->size() * sizeof(float));
    Params params{};
    glm::mat4 vp = raster_view_proj(camera, width, height);
    std::memcpy(params.view_proj, glm::value_ptr(vp), sizeof(params.view_proj));
    params.width = width;
    params.height = height;
    params.force_bits = uint32_t(options.force_bits);
    params.min_batch_px = options.min_batch_px;
    // Without HQS only the nearest depth itself is kept; a hair of tolerance absorbs rounding
    // differences between the two passes' compiled code.
    params.depth_tolerance = options.hqs ? options.hqs_tolerance : 1e-6f;
    params.depth_stride = use64 ? 2 : 1;
    params.depth_word = use64 ? 1 : 0;
    params.edl_strength = options.edl_strength;
    params.edl_radius = options.edl_radius;
    params.background[0] = options.background.r;
    params.background[1] = options.background.g;
    params.background[2] = options.background.b;
    params.background[3] = 1.0f;
    params.sky = sky_uniforms(options.sky, glm::dmat4(vp), width, height);
    if (cloud.shading)
      gpu::write_buffer(ctx, cloud.shading.get(), 0, shading_uniforms(options.shading, camera));
    thread_local std::vector<GpuBatch> table;  // every frame: keep the capacity
    for (auto& seg : cloud.segments) {
      params.segment_base = uint32_t(seg.first_point);
      params.batch_count = seg.batch_count;
      params.segment_points = seg.point_count;
      gpu::write_buffer(ctx, seg.params.get(), 0, params);
      table.resize(seg.batch_count);
      // (A thread_local named in a lambda is the running thread's: the workers get this one.)
      GpuBatch* rows = table.data();
      auto convert = [&](size_t begin, size_t end) {
        for (size_t i = begin; i < end; ++i) {
          const Batch& b = cloud.batches[seg.first_batch + i];
          glm::vec3 offset(b.min - camera.position), size(b.size);
          rows[i] = {{offset.x, offset.y, offset.z},
                     b.count,
                     {size.x, size.y, size.z},
                     uint32_t(b.first - seg.first_point)};
        }
      };
      // A virtualized cloud has a batch or more per drawn pointlet (100K and more a frame):
      // those tables are made on every core.
      if (seg.batch_count >= 2 * kFrameTablePiece)
        batching_pool().parallel_for(seg.batch_count, kFrameTablePiece, convert);
      else
        convert(0, seg.batch_count);
      if (!table.empty())
        gpu::write_buffer(ctx, seg.batches.get(), 0, table.data(), table.size() * sizeof(GpuBatch));
    }
  };

  if (translucent) graph.add_prepare([&p](gpu::Context& ctx) { ensure_split_pipelines(ctx, p); });
  gpu::PassBuilder clear_pass = graph.add_pass(
      "raster-clear", gpu::PassKind::Compute,
      [&p, &cloud, upload_frame, depth_name, accum_name, groups_x, groups_y, accumulate, events,
       events_name, hint, hint_name](gpu::PassContext& pc) {
        gpu::Context& ctx = pc.gpu();
        upload_frame(ctx);
        wgpuCommandEncoderClearBuffer(pc.encoder(), p.counters.get(), 0, WGPU_WHOLE_SIZE);
        if (hint)
          wgpuCommandEncoderClearBuffer(pc.encoder(), pc.buffer(hint_name), 0, WGPU_WHOLE_SIZE);
        if (events)  // the regions' counters
          wgpuCommandEncoderClearBuffer(pc.encoder(), pc.buffer(events_name), 0, kEventRegions * 4);
        if (cloud.segments.empty()) return;
        // Without accumulation the resolve pass writes every pixel of the colour sums
        // (empty ones too): only the depth buffer needs clearing, a third of the bytes.
        // CPU-shaped, clearBuffer zeroes the sums (a memset there: on SwiftShader the pass 1.5x
        // faster than storing them from the shader).
        const bool sums_by_buffer_clear = accumulate && cpu_shaped(p.kernel);
        if (sums_by_buffer_clear)
          wgpuCommandEncoderClearBuffer(pc.encoder(), pc.buffer(accum_name), 0, WGPU_WHOLE_SIZE);
        const gpu::ComputePipeline& clear =
            accumulate && !sums_by_buffer_clear ? p.clear : p.clear_depth;
        auto layout = gpu::bind_group_layout_of(clear);
        auto group = gpu::create_bind_group(ctx, layout.get(),
                                            {gpu::bind_buffer(0, cloud.segments[0].params.get()),
                                             gpu::bind_buffer(1, pc.buffer(depth_name)),
                                             gpu::bind_buffer(2, pc.buffer(accum_name))});
        auto pass = pc.begin_compute_pass();
        gpu::dispatch(pass.get(), clear.get(), {group.get()}, groups_x, groups_y);
        wgpuComputePassEncoderEnd(pass.get());
      });
  // With events, a word after the last pixel holds raster-events' overflow flag.
  clear_pass
      .create_buffer(depth_name,
                     {pixels * (use64 ? 8 : 4) + (events ? 4 : 0), WGPUBufferUsage_Storage})
      .create_buffer(accum_name, {pixels * 16, WGPUBufferUsage_Storage | WGPUBufferUsage_CopyDst});
  if (events)
    clear_pass.create_buffer(events_name,
                             {event_bytes, WGPUBufferUsage_Storage | WGPUBufferUsage_CopyDst});
  if (hint)
    clear_pass.create_buffer(hint_name,
                             {pixels * 4, WGPUBufferUsage_Storage | WGPUBufferUsage_CopyDst});

  gpu::PassBuilder depth_pass = graph.add_pass(
      "raster-depth", gpu::PassKind::Compute,
      [&p, &cloud, use64, events, translucent, depth_name, events_name, hint,
       hint_name](gpu::PassContext& pc) {
        gpu::Context& ctx = pc.gpu();
        const gpu::ComputePipeline& pipeline = translucent
                                                   ? (events ? p.split.depth_events : p.split.depth)
                                               : use64  ? p.raster64
                                               : events ? p.depth32_events
                                                        : p.depth32;
        auto layout = gpu::bind_group_layout_of(pipeline);
        std::vector<gpu::BindGroup> groups;
        WGPUBuffer depth = pc.buffer(depth_name);
        for (auto& seg : cloud.segments) {
          // The early depth test reads the depth through a plain binding of the same buffer
          // (binding 8: the 64-bit pass, the fallback's on wgpu-native, which allows the
          // aliasing).
          std::vector<gpu::Binding> bindings = {gpu::bind_buffer(0, seg.params.get()),
                                                gpu::bind_buffer(1, seg.batches.get()),
                                                gpu::bind_buffer(2, seg.coarse.get()),
                                                gpu::bind_buffer(3, seg.medium.get()),
                                                gpu::bind_buffer(4, seg.fine.get()),
                                                gpu::bind_buffer(5, depth),
                                                gpu::bind_buffer(7, p.counters.get()),
                                                gpu::bind_buffer(9, seg.attributes.get()),
                                                gpu::bind_buffer(11, p.filter_uniforms.get()),
                                                gpu::bind_buffer(12, p.polygon_vertices.get())};
          if ((use64 && !p.visibility_vec2u) || p.depth32_plain_early)
            bindings.push_back(gpu::bind_buffer(8, depth));
          if (events) bindings.push_back(gpu::bind_buffer(6, pc.buffer(events_name)));
          if (hint) bindings.push_back(gpu::bind_buffer(8, pc.buffer(hint_name)));
          groups.push_back(gpu::create_bind_group(ctx, layout.get(), bindings));
        }
        auto pass = pc.begin_compute_pass();
        for (size_t s = 0; s < cloud.segments.size(); ++s)
          dispatch_batches(pass.get(), pipeline.get(), groups[s].get(),
                           cloud.segments[s].batch_count);
        wgpuComputePassEncoderEnd(pass.get());
      });
  depth_pass.write(depth_name);
  if (events) depth_pass.write(events_name);
  if (hint) depth_pass.write(hint_name);

  if (accumulate) {
    graph
        .add_pass("raster-accumulate", gpu::PassKind::Compute,
                  [&p, &cloud, depth_name, accum_name, hqs = options.hqs,
                   translucent](gpu::PassContext& pc) {
                    gpu::Context& ctx = pc.gpu();
                    const auto& pipelines = translucent ? p.split.accumulate : p.accumulate;
                    const auto& colours =
                        translucent ? p.split.accumulate_colours : p.accumulate_colours;
                    const gpu::ComputePipeline& pipeline = hqs ? pipelines : colours;
                    const auto groups = accumulate_bind_groups(
                        ctx, pipeline, cloud, p, pc.buffer(depth_name), pc.buffer(accum_name));
                    auto pass = pc.begin_compute_pass();
                    for (size_t s = 0; s < cloud.segments.size(); ++s)
                      dispatch_batches(pass.get(), pipeline.get(), groups[s].get(),
                                       cloud.segments[s].batch_count);
                    wgpuComputePassEncoderEnd(pass.get());
                  })
        .read(depth_name)
        .write(accum_name);
  } else {
    if (events) {
      graph
          .add_pass(
              "raster-events", gpu::PassKind::Compute,
              [&p, &cloud, depth_name, events_name, visibility_name, groups_x,
               groups_y](gpu::PassContext& pc) {
                gpu::Context& ctx = pc.gpu();
                if (cloud.segments.empty()) return;
                // The colour pass's full dispatch a segment (as dispatch_batches sizes it).
                std::vector<uint32_t> sizes;
                for (const auto& seg : cloud.segments) {
                  const uint32_t x = std::min(seg.batch_count, kDispatchRow);
                  sizes.insert(sizes.end(),
                               {x, (seg.batch_count + kDispatchRow - 1) / kDispatchRow, 1u});
                }
                const uint64_t bytes = sizes.size() * 4;
                if (!p.events_dispatch || wgpuBufferGetSize(p.events_dispatch.get()) != bytes)
                  p.events_dispatch = gpu::create_buffer(
                      ctx, bytes,
                      WGPUBufferUsage_Storage | WGPUBufferUsage_Indirect | WGPUBufferUsage_CopyDst,
                      "raster-events-dispatch");
                gpu::write_buffer(ctx, p.events_dispatch.get(), 0, sizes.data(), bytes);
                auto group =
                    gpu::create_bind_group(ctx, p.events_layout.get(),
                                           {gpu::bind_buffer(0, cloud.segments[0].params.get()),
                                            gpu::bind_buffer(1, pc.buffer(depth_name)),
                                            gpu::bind_buffer(2, pc.buffer(events_name)),
                                            gpu::bind_buffer(3, pc.buffer(visibility_name)),
                                            gpu::bind_buffer(4, p.counters.get()),
                                            gpu::bind_buffer(5, p.events_dispatch.get())});
                auto pass = pc.begin_compute_pass();
                gpu::dispatch(pass.get(), p.events_overflow.get(), {group.get()}, 1, 1);
                gpu::dispatch(pass.get(), p.events_init.get(), {group.get()}, groups_x, groups_y);
                gpu::dispatch(pass.get(), p.events_scan.get(), {group.get()},
                              uint32_t(kEventRegions), 1);
                wgpuComputePassEncoderEnd(pass.get());
              })
          .read(events_name)
          .write(depth_name)
          .create_buffer(visibility_name, {pixels * 8, WGPUBufferUsage_Storage});
    }
    const std::string& visibility = events ? visibility_name : depth_name;
    graph
        .add_pass(
            "raster-resolve", gpu::PassKind::Compute,
            [&p, &cloud, depth_name = visibility, accum_name, groups_x,
             groups_y](gpu::PassContext& pc) {
              gpu::Context& ctx = pc.gpu();
              auto layout = gpu::bind_group_layout_of(p.resolve);
              std::vector<gpu::BindGroup> groups;
              for (auto& seg : cloud.segments)
                groups.push_back(gpu::create_bind_group(
                    ctx, layout.get(),
                    {gpu::bind_buffer(0, seg.params.get()),
                     gpu::bind_buffer(1, pc.buffer(depth_name)),
                     gpu::bind_buffer(2, seg.color.get()),
                     gpu::bind_buffer(3, pc.buffer(accum_name)),
                     gpu::bind_buffer(4, seg.batches.get()), gpu::bind_buffer(5, seg.coarse.get()),
                     gpu::bind_buffer(6, seg.medium.get()), gpu::bind_buffer(7, seg.fine.get()),
                     gpu::bind_buffer(9, seg.attributes.get()),
                     gpu::bind_buffer(10, cloud.shading.get()),
                     gpu::bind_buffer(11, p.filter_uniforms.get()),
                     gpu::bind_buffer(12, p.polygon_vertices.get())}));
              auto pass = pc.begin_compute_pass();
              for (size_t s = 0; s < cloud.segments.size(); ++s)
                gpu::dispatch(pass.get(), p.resolve.get(), {groups[s].get()}, groups_x, groups_y);
              wgpuComputePassEncoderEnd(pass.get());
            })
        .read(visibility)
        .write(accum_name);
    if (events) {
      // Adds the colours where the events overflowed (the resolve wrote zeros there); else
      // raster-events made its dispatches empty.
      graph
          .add_pass("raster-accumulate", gpu::PassKind::Compute,
                    [&p, &cloud, depth_name, accum_name, translucent](gpu::PassContext& pc) {
                      gpu::Context& ctx = pc.gpu();
                      if (cloud.segments.empty()) return;
                      const gpu::ComputePipeline& pipeline =
                          translucent ? p.split.accumulate_colours : p.accumulate_colours;
                      const auto groups = accumulate_bind_groups(
                          ctx, pipeline, cloud, p, pc.buffer(depth_name), pc.buffer(accum_name));
                      auto pass = pc.begin_compute_pass();
                      wgpuComputePassEncoderSetPipeline(pass.get(), pipeline.get());
                      for (size_t s = 0; s < cloud.segments.size(); ++s) {
                        wgpuComputePassEncoderSetBindGroup(pass.get(), 0, groups[s].get(), 0,
                                                           nullptr);
                        wgpuComputePassEncoderDispatchWorkgroupsIndirect(
                            pass.get(), p.events_dispatch.get(), s * 12);
                      }
                      wgpuComputePassEncoderEnd(pass.get());
                    })
          .read(depth_name)
          .write(accum_name);
    }
  }

  // Seed 002, III-D: the occlusion check, then hole filling, each into a buffer of its own;
  // before them, points larger than a pixel dilated (colour and depth).
  std::string shown = accum_name, depth_shown = depth_name;
  struct FillParams {
    uint32_t width, height, radius, depth_stride, depth_word;
    float beta, pixel_tan;
    float radius2;
  };
  const double tan_half_x = std::tan(camera.fov_y * 0.5) * double(width) / double(height);
  const float pixel_tan = float(std::tan(2.0 * std::atan(tan_half_x) / double(width)));
  auto add_post_pass = [&](const char* name, const gpu::ComputePipeline& pipeline,
                           const gpu::Buffer& uniforms, uint32_t radius, const std::string& out) {
    const FillParams fp{
        width,     height, radius, use64 ? 2u : 1u, use64 ? 1u : 0u, options.occlusion_beta,
        pixel_tan, 0};
    graph
        .add_pass(
            name, gpu::PassKind::Compute,
            [&p, &pipeline, &uniforms, fp, depth_name = depth_shown, in = shown, out, groups_x,
             groups_y](gpu::PassContext& pc) {
              gpu::Context& ctx = pc.gpu();
              gpu::write_buffer(ctx, uniforms.get(), 0, fp);
              auto group = gpu::create_bind_group(
                  ctx, p.fill_layout.get(),
                  {gpu::bind_buffer(0, uniforms.get()), gpu::bind_buffer(1, pc.buffer(depth_name)),
                   gpu::bind_buffer(2, pc.buffer(in)), gpu::bind_buffer(3, pc.buffer(out))});
              auto pass = pc.begin_compute_pass();
              gpu::dispatch(pass.get(), pipeline.get(), {group.get()}, groups_x, groups_y);
              wgpuComputePassEncoderEnd(pass.get());
            })
        .read(depth_shown)
        .read(shown)
        .create_buffer(out, {pixels * 16, WGPUBufferUsage_Storage});
    shown = out;
  };
  // The display reads through the dilation's winners where it is their only reader (no
  // resolve pass; ComputeRasterPipeline::display_winner).
  const bool occlusion = options.occlusion_beta > 0.0f && options.occlusion_radius > 0;
  const bool winner_display =
      large && p.display_winner && !occlusion && options.fill_radius == 0 && !translucent &&
      (!options.storage_target || !p.display_compute || p.display_compute_winner);
  if (large) {
    // Offset codes hold 8 bits a coordinate (compute_raster_fill.wgsl): points up to 254 px.
    const float r = std::min(options.point_size * 0.5f, 127.0f);
    const FillParams fp{
        width,     height, uint32_t(std::ceil(r)), use64 ? 2u : 1u, use64 ? 1u : 0u, 0.0f,
        pixel_tan, r * r};
    const uint64_t depth_bytes = pixels * (use64 ? 8 : 4);
    auto dilate = graph.add_pass(
        "raster-dilate", gpu::PassKind::Compute,
        [&p, fp, depth_name, in = shown, groups_x, groups_y, winner_display](gpu::PassContext& pc) {
          gpu::Context& ctx = pc.gpu();
          gpu::write_buffer(ctx, p.dilate_params.get(), 0, fp);
          const bool gather = p.dilate_gather;
          const WGPUBuffer winner = pc.buffer("raster-dilate-winner");
          // Without the resolve, its outputs' bindings take stand-ins nothing reads.
          const WGPUBuffer dilated =
              winner_display ? p.dilate_unused[0].get() : pc.buffer("raster-dilated");
          const WGPUBuffer dilated_depth =
              winner_display ? p.dilate_unused[1].get() : pc.buffer("raster-dilated-depth");
          auto group = gpu::create_bind_group(
              ctx, p.dilate_layout.get(),
              {gpu::bind_buffer(0, p.dilate_params.get()),
               gpu::bind_buffer(1, pc.buffer(depth_name)), gpu::bind_buffer(2, pc.buffer(in)),
               gpu::bind_buffer(3, dilated), gpu::bind_buffer(4, dilated_depth),
               gpu::bind_buffer(5, winner)});
          // By scatter from the drawn pixels on CPU adapters (SwiftShader, lavapipe), where
          // the window over every pixel cost most of the frame; by that window on GPUs, where
          // views are dense and it measured 1.6x faster (bench/RESULTS.md, "Dilation").
          // STIPPLE_DILATE=gather|scatter chooses for the bench. The same image either way.
          if (!gather) wgpuCommandEncoderClearBuffer(pc.encoder(), winner, 0, WGPU_WHOLE_SIZE);
          auto pass = pc.begin_compute_pass();
          if (gather) {
            gpu::dispatch(pass.get(), p.dilate.get(), {group.get()}, groups_x, groups_y);
          } else {
            for (const auto* pipeline : {&p.dilate_depth, &p.dilate_offset})
              gpu::dispatch(pass.get(), pipeline->get(), {group.get()}, groups_x, groups_y);
            if (!winner_display)
              gpu::dispatch(pass.get(), p.dilate_resolve.get(), {group.get()}, groups_x, groups_y);
          }
          wgpuComputePassEncoderEnd(pass.get());
        });
    dilate.read(depth_name)
        .read(shown)
        .create_buffer("raster-dilate-winner",
                       {pixels * 8, WGPUBufferUsage_Storage | WGPUBufferUsage_CopyDst});
    if (winner_display) {
      depth_shown = "raster-dilate-winner";  // `shown` stays the sums before dilation
    } else {
      dilate.create_buffer("raster-dilated", {pixels * 16, WGPUBufferUsage_Storage})
          .create_buffer("raster-dilated-depth", {depth_bytes, WGPUBufferUsage_Storage});
      shown = "raster-dilated";
      depth_shown = "raster-dilated-depth";
    }
  }
  if (occlusion)
    add_post_pass("raster-occlusion", p.occlusion, p.occlusion_params, options.occlusion_radius,
                  "raster-visible");
  if (options.fill_radius > 0)
    add_post_pass("raster-fill", p.fill, p.fill_params, options.fill_radius, "raster-filled");

  // The translucent points over the opaque depth the display shows (dilated where points are
  // larger than a pixel): their sums, cleared here, for the display.
  const std::string translucent_name = "raster-translucent";
  if (translucent) {
    const float r = large ? options.point_size * 0.5f : 0.0f;
    const DiscParams disc{
        width, height, uint32_t(std::ceil(r)), use64 ? 2u : 1u, use64 ? 1u : 0u, 0.0f, 0.0f, r * r};
    graph
        .add_pass(
            "raster-translucent", gpu::PassKind::Compute,
            [&p, &cloud, disc, depth_name = depth_shown, translucent_name](gpu::PassContext& pc) {
              gpu::Context& ctx = pc.gpu();
              WGPUBuffer sums = pc.buffer(translucent_name);
              wgpuCommandEncoderClearBuffer(pc.encoder(), sums, 0, WGPU_WHOLE_SIZE);
              gpu::write_buffer(ctx, p.split.params.get(), 0, disc);
              const gpu::ComputePipeline& pipeline = p.split.translucent;
              auto layout = gpu::bind_group_layout_of(pipeline);
              std::vector<gpu::BindGroup> groups;
              for (auto& seg : cloud.segments)
                groups.push_back(gpu::create_bind_group(
                    ctx, layout.get(),
                    {gpu::bind_buffer(0, seg.params.get()), gpu::bind_buffer(1, seg.batches.get()),
                     gpu::bind_buffer(2, seg.coarse.get()), gpu::bind_buffer(3, seg.medium.get()),
                     gpu::bind_buffer(4, seg.fine.get()), gpu::bind_buffer(5, seg.color.get()),
                     gpu::bind_buffer(6, pc.buffer(depth_name)), gpu::bind_buffer(7, sums),
                     gpu::bind_buffer(8, p.split.params.get()),
                     gpu::bind_buffer(9, seg.attributes.get()),
                     gpu::bind_buffer(11, p.filter_uniforms.get()),
                     gpu::bind_buffer(12, p.polygon_vertices.get())}));
              auto pass = pc.begin_compute_pass();
              for (size_t s = 0; s < cloud.segments.size(); ++s)
                dispatch_batches(pass.get(), pipeline.get(), groups[s].get(),
                                 cloud.segments[s].batch_count);
              wgpuComputePassEncoderEnd(pass.get());
            })
        .read(depth_shown)
        .create_buffer(translucent_name,
                       {pixels * 20, WGPUBufferUsage_Storage | WGPUBufferUsage_CopyDst});
  }

  if (!options.depth_texture.empty()) {
    // The depth for later passes (splats): from the buffer the display reads.
    graph.add_prepare([&p](gpu::Context& ctx) {
      if (p.depth_export) return;
      gpu::ShaderModule module =
          gpu::create_shader_from_file(ctx, "compute_raster_depth_export.wgsl");
      WGPUDepthStencilState depth = WGPU_DEPTH_STENCIL_STATE_INIT;
      depth.format = gpu::native(WGPUTextureFormat_Depth32Float);
      depth.depthWriteEnabled = WGPUOptionalBool_True;
      depth.depthCompare = WGPUCompareFunction_Always;
      WGPUFragmentState fragment = WGPU_FRAGMENT_STATE_INIT;
      fragment.module = module.get();
      fragment.entryPoint = gpu::to_view("fs_depth");
      WGPURenderPipelineDescriptor desc = WGPU_RENDER_PIPELINE_DESCRIPTOR_INIT;
      desc.label = gpu::to_view("raster-depth-export");
      desc.vertex.module = module.get();
      desc.vertex.entryPoint = gpu::to_view("vs_fullscreen");
      desc.primitive.topology = WGPUPrimitiveTopology_TriangleList;
      desc.depthStencil = &depth;
      desc.multisample.count = 1;
      desc.multisample.mask = ~0u;
      desc.fragment = &fragment;
      p.depth_export = gpu::RenderPipeline(wgpuDeviceCreateRenderPipeline(ctx.device.get(), &desc));
      if (p.display_winner) {  // its form reading the dilation's winners
        WGPUConstantEntry winner = WGPU_CONSTANT_ENTRY_INIT;
        winner.key = gpu::to_view("WINNER");
        winner.value = 1.0;
        fragment.constantCount = 1;
        fragment.constants = &winner;
        p.depth_export_winner =
            gpu::RenderPipeline(wgpuDeviceCreateRenderPipeline(ctx.device.get(), &desc));
      }
    });
    const std::string target = options.depth_texture;
    graph
        .add_pass(
            "raster-depth-export", gpu::PassKind::Render,
            [&p, &cloud, target, depth_name = depth_shown, winner_display](gpu::PassContext& pc) {
              WGPURenderPassDepthStencilAttachment depth =
                  WGPU_RENDER_PASS_DEPTH_STENCIL_ATTACHMENT_INIT;
              depth.view = pc.view(target);
              depth.depthLoadOp = WGPULoadOp_Clear;
              depth.depthStoreOp = WGPUStoreOp_Store;
              depth.depthClearValue = 0.0f;
              WGPURenderPassDescriptor desc = WGPU_RENDER_PASS_DESCRIPTOR_INIT;
              desc.depthStencilAttachment = &depth;
              auto pass = pc.begin_render_pass(desc);
              if (!cloud.segments.empty()) {
                const gpu::RenderPipeline& pipeline =
                    winner_display ? p.depth_export_winner : p.depth_export;
                auto layout = gpu::bind_group_layout_of(pipeline);
                auto group =
                    gpu::create_bind_group(pc.gpu(), layout.get(),
                                           {gpu::bind_buffer(0, cloud.segments[0].params.get()),
                                            gpu::bind_buffer(2, pc.buffer(depth_name))});
                wgpuRenderPassEncoderSetPipeline(pass.get(), pipeline.get());
                gpu::set_bind_groups(pass.get(), {group.get()});
                wgpuRenderPassEncoderDraw(pass.get(), 3, 1, 0, 0);
              }
              wgpuRenderPassEncoderEnd(pass.get());
            })
        .read(depth_shown)
        .create_texture(target,
                        {width, height, WGPUTextureFormat_Depth32Float,
                         WGPUTextureUsage_RenderAttachment | WGPUTextureUsage_TextureBinding});
  }

  if (options.storage_target && p.display_compute) {
    const uint32_t gx = (width + 15) / 16, gy = (height + 15) / 16;
    auto display = graph.add_pass(
        "raster-display", gpu::PassKind::Compute,
        [&p, &cloud, accum_name = shown, color_target, depth_name = depth_shown, gx, gy,
         translucent, translucent_name, winner_display](gpu::PassContext& pc) {
          gpu::Context& ctx = pc.gpu();
          if (cloud.segments.empty()) return;
          const gpu::ComputePipeline& pipeline = translucent      ? p.split.display_compute
                                                 : winner_display ? p.display_compute_winner
                                                                  : p.display_compute;
          auto layout = gpu::bind_group_layout_of(pipeline);
          std::vector<gpu::Binding> bindings = {gpu::bind_buffer(0, cloud.segments[0].params.get()),
                                                gpu::bind_buffer(1, pc.buffer(accum_name)),
                                                gpu::bind_buffer(2, pc.buffer(depth_name)),
                                                gpu::bind_texture(3, pc.view(color_target))};
          if (translucent) bindings.push_back(gpu::bind_buffer(4, pc.buffer(translucent_name)));
          auto group = gpu::create_bind_group(ctx, layout.get(), bindings);
          auto pass = pc.begin_compute_pass();
          gpu::dispatch(pass.get(), pipeline.get(), {group.get()}, gx, gy);
          wgpuComputePassEncoderEnd(pass.get());
        });
    display.read(shown).read(depth_shown).write(color_target);
    if (translucent) display.read(translucent_name);
    return;
  }
  auto display = graph.add_pass(
      "raster-display", gpu::PassKind::Render,
      [&p, &cloud, accum_name = shown, color_target, depth_name = depth_shown, translucent,
       translucent_name, winner_display](gpu::PassContext& pc) {
        gpu::Context& ctx = pc.gpu();
        const gpu::RenderPipeline& pipeline = translucent      ? p.split.display
                                              : winner_display ? p.display_winner
                                                               : p.display;
        auto layout = gpu::bind_group_layout_of(pipeline);
        if (cloud.segments.empty()) return;
        std::vector<gpu::Binding> bindings = {gpu::bind_buffer(0, cloud.segments[0].params.get()),
                                              gpu::bind_buffer(1, pc.buffer(accum_name)),
                                              gpu::bind_buffer(2, pc.buffer(depth_name))};
        if (translucent) bindings.push_back(gpu::bind_buffer(4, pc.buffer(translucent_name)));
        auto group = gpu::create_bind_group(ctx, layout.get(), bindings);
        gpu::draw_fullscreen(pc, pc.view(color_target), pipeline.get(), {group.get()},
                             WGPUColor{0, 0, 0, 1});
      });
  display.read(shown).read(depth_shown).write(color_target);
  if (translucent) display.read(translucent_name);
}

RasterCounters read_raster_counters(gpu::Context& ctx, const ComputeRasterPipeline& p) {
  auto bytes = gpu::read_buffer(ctx, p.counters.get(), 0, kCounterWords * 4);
  uint32_t w[kCounterWords];
  std::memcpy(w, bytes.data(), sizeof(w));
  RasterCounters c;
  c.batches_processed = w[0];
  c.batches_rendered = w[1];
  c.batches_culled = w[2];
  c.batches_lod_skipped = w[3];
  c.points_rendered = w[4];
  for (int k = 0; k < 3; ++k) {
    c.batches_by_bits[k] = w[5 + k];
    c.points_by_bits[k] = w[8 + k];
  }
  c.events = w[11];
  c.events_overflowed = w[12] != 0;
  return c;
}

}  // namespace stipple::pc
