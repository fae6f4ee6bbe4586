#include "stipple/splats/splats.hpp"

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstring>
#include <memory>
#include <string_view>
#include <utility>

#include <glm/gtc/packing.hpp>
#include <glm/mat3x3.hpp>
#include <glm/matrix.hpp>

#include "stipple/core/error.hpp"
#include "stipple/core/log.hpp"
#include "stipple/renderer/shader_preprocessor.hpp"
#include "stipple/renderer/staging.hpp"

namespace stipple::splats {
namespace {

constexpr uint32_t kProjectWorkgroup = 256;  // splat_project.wgsl's workgroup size
constexpr uint32_t kMaxGroupsX = 65535;

// splat_common.wgsl's Splat.
struct GpuSplat {
  float position[3];
  float opacity;
  float scale[3];
  uint32_t rot_xy, rot_zw, dc_rg, dc_b, pad;
};
static_assert(sizeof(GpuSplat) == 48);

// Bits of splat_common.wgsl's depth key: the view depth's float bits, all of them (a coarser key
// makes ties, and ties flicker: see there).
constexpr uint32_t kDepthKeyBits = 32;

// splat_common.wgsl's SplatFrame.
struct FrameUniforms {
  float local_to_view[16];
  float world_to_local[16];
  float view_rotation[16];
  float offset[3];
  uint32_t count;
  float focal[2];
  float tan_fov[2];
  float viewport[2];
  float near;
  uint32_t sh_degree;
  uint32_t sh_stride;
  uint32_t pad[3];
};
static_assert(sizeof(FrameUniforms) == 256);

constexpr uint64_t kProjectedBytes = 32;  // splat_common.wgsl's Projected

uint32_t pack_half2(float a, float b) {
  return uint32_t(glm::packHalf1x16(a)) | uint32_t(glm::packHalf1x16(b)) << 16;
}

void store_mat3(float* out, const glm::dmat3& m) {
  for (int c = 0; c < 4; ++c)
    for (int r = 0; r < 4; ++r) out[c * 4 + r] = c < 3 && r < 3 ? float(m[c][r]) : 0.0f;
}

FrameUniforms make_frame(const GpuSplats& s, const Camera& camera, uint32_t width,
                         uint32_t height) {
  FrameUniforms f{};
  // World to the reference rasterizer's view axes: x right, y down, z forward (the camera looks
  // along -Z with y up).
  const glm::dmat3 flip(1, 0, 0, 0, -1, 0, 0, 0, -1);
  const glm::dmat3 world_to_view = flip * glm::dmat3(camera.view_rotation());
  store_mat3(f.local_to_view, world_to_view * s.linear);
  store_mat3(f.world_to_local, glm::inverse(s.linear));
  store_mat3(f.view_rotation, world_to_view);
  const glm::dvec3 offset = s.centre - camera.position;
  for (int i = 0; i < 3; ++i) f.offset[i] = float(offset[i]);
  f.count = s.count;
  const double tan_y = std::tan(camera.fov_y * 0.5);
  const double tan_x = tan_y * double(width) / double(height);
  f.tan_fov[0] = float(tan_x);
  f.tan_fov[1] = float(tan_y);
  f.focal[0] = float(double(width) / (2.0 * tan_x));
  f.focal[1] = float(double(height) / (2.0 * tan_y));
  f.viewport[0] = float(width);
  f.viewport[1] = float(height);
  f.near = float(camera.near_plane);
  f.sh_degree = uint32_t(s.sh_degree);
  f.sh_stride = s.sh_stride;
  return f;
}

// One layout for both draw pipelines (with and without the depth test), so one bind group
// serves either: the frame's uniforms, the projected splats, the sorted keys and values.
gpu::BindGroupLayout make_draw_layout(gpu::Context& ctx) {
  WGPUBindGroupLayoutEntry entries[4];
  for (uint32_t i = 0; i < 4; ++i) {
    entries[i] = WGPU_BIND_GROUP_LAYOUT_ENTRY_INIT;
    entries[i].binding = i;
    entries[i].visibility = WGPUShaderStage_Vertex | WGPUShaderStage_Fragment;
    entries[i].buffer.type =
        i == 0 ? WGPUBufferBindingType_Uniform : WGPUBufferBindingType_ReadOnlyStorage;
  }
  for (uint32_t i = 1; i < 4; ++i) entries[i].visibility = WGPUShaderStage_Vertex;
  WGPUBindGroupLayoutDescriptor desc = WGPU_BIND_GROUP_LAYOUT_DESCRIPTOR_INIT;
  desc.label = gpu::to_view("splat-draw");
  desc.entryCount = 4;
  desc.entries = entries;
  return gpu::BindGroupLayout(wgpuDeviceCreateBindGroupLayout(ctx.device.get(), &desc));
}

gpu::RenderPipeline make_draw_pipeline(gpu::Context& ctx, WGPUShaderModule module,
                                       WGPUPipelineLayout layout, WGPUTextureFormat color_format,
                                       WGPUTextureFormat depth_format, bool depth_test) {
  // Premultiplied alpha, back to front: dst = src + (1 - src.a) dst.
  WGPUBlendState blend = WGPU_BLEND_STATE_INIT;
  blend.color = {WGPUBlendOperation_Add, WGPUBlendFactor_One, WGPUBlendFactor_OneMinusSrcAlpha};
  blend.alpha = {WGPUBlendOperation_Add, WGPUBlendFactor_One, WGPUBlendFactor_OneMinusSrcAlpha};
  WGPUColorTargetState target = WGPU_COLOR_TARGET_STATE_INIT;
  target.format = gpu::native(color_format);
  target.writeMask = WGPUColorWriteMask_All;
  target.blend = &blend;
  WGPUFragmentState fragment = WGPU_FRAGMENT_STATE_INIT;
  fragment.module = module;
  fragment.entryPoint = gpu::to_view("fs_splat");
  fragment.targetCount = 1;
  fragment.targets = &target;
  // Reverse Z: nearer is greater; tested against the points' depth, never written.
  WGPUDepthStencilState depth = WGPU_DEPTH_STENCIL_STATE_INIT;
  depth.format = gpu::native(depth_format);
  depth.depthWriteEnabled = WGPUOptionalBool_False;
  depth.depthCompare = WGPUCompareFunction_Greater;
  WGPURenderPipelineDescriptor desc = WGPU_RENDER_PIPELINE_DESCRIPTOR_INIT;
  desc.label = gpu::to_view(depth_test ? "splat-draw" : "splat-draw-no-depth");
  desc.layout = layout;
  desc.vertex.module = module;
  desc.vertex.entryPoint = gpu::to_view("vs_splat");
  desc.primitive.topology = WGPUPrimitiveTopology_TriangleStrip;
  desc.primitive.cullMode = WGPUCullMode_None;
  desc.depthStencil = depth_test ? &depth : nullptr;
  desc.multisample.count = 1;
  desc.multisample.mask = ~0u;
  desc.fragment = &fragment;
  return gpu::RenderPipeline(wgpuDeviceCreateRenderPipeline(ctx.device.get(), &desc));
}

void ensure_groups(gpu::Context& ctx, const SplatPipelines& p, GpuSplats& s) {
  if (s.project_group) return;
  auto project_layout = gpu::bind_group_layout_of(p.project);
  s.project_group = gpu::create_bind_group(
      ctx, project_layout.get(),
      {gpu::bind_buffer(0, s.frame_uniforms.get()), gpu::bind_buffer(1, s.splats.get()),
       gpu::bind_buffer(2, s.sh.get()), gpu::bind_buffer(3, s.projected.get()),
       gpu::bind_buffer(4, s.sort.keys[0].get()), gpu::bind_buffer(5, s.sort.values[0].get()),
       gpu::bind_buffer(6, s.args.get())},
      "splat-project");
  const uint32_t r = radix_sort_result(kDepthKeyBits);
  s.draw_group = gpu::create_bind_group(
      ctx, p.draw_layout.get(),
      {gpu::bind_buffer(0, s.frame_uniforms.get()), gpu::bind_buffer(1, s.projected.get()),
       gpu::bind_buffer(2, s.sort.keys[r].get()), gpu::bind_buffer(3, s.sort.values[r].get())},
      "splat-draw");
}

// splat_tiles.wgsl's TileParams.
struct TileParams {
  uint32_t tiles_x, tiles_y, capacity, pair_capacity, blocks, has_depth, pad0, pad1;
};

constexpr uint32_t kTile = 16;
constexpr uint32_t kScanBlock = 2048;  // splat_tiles.wgsl's BLOCK

// Workgroups for `items` items of `per_group` each as a 2D grid within the per-dimension limit.
std::pair<uint32_t, uint32_t> grid(uint64_t items, uint32_t per_group) {
  const uint32_t groups = uint32_t(std::max<uint64_t>(1, (items + per_group - 1) / per_group));
  const uint32_t x = std::min(groups, kMaxGroupsX);
  return {x, (groups + x - 1) / x};
}

void ensure_tile_pipelines(gpu::Context& ctx, SplatPipelines& p) {
  if (p.tile_pipelines) return;
  using B = gpu::BufferBinding;
  p.tile_layout = gpu::create_compute_layout(
      ctx,
      {B::Uniform, B::Uniform, B::ReadOnlyStorage, B::ReadOnlyStorage, B::ReadOnlyStorage,
       B::ReadOnlyStorage, B::Storage, B::Storage, B::Storage, B::Storage},
      "splat-tiles");
  p.tile_pipeline_layout = gpu::create_pipeline_layout(ctx, {p.tile_layout.get()});
  gpu::ShaderModule bin = gpu::create_shader_from_file(ctx, "splat_tiles.wgsl");
  auto make = [&](const char* entry) {
    return gpu::create_compute_pipeline(ctx, bin.get(), entry, p.tile_pipeline_layout.get(), entry);
  };
  p.tile_block_sums = make("cs_block_sums");
  p.tile_scan_blocks = make("cs_scan_blocks");
  p.tile_block_apply = make("cs_block_apply");
  p.tile_emit = make("cs_emit");
  p.tile_clear_ranges = make("cs_clear_ranges");
  p.tile_ranges = make("cs_ranges");
  gpu::ShaderModule raster = gpu::create_shader_from_file(ctx, "splat_tiles_raster.wgsl");
  p.tile_raster =
      gpu::create_compute_pipeline(ctx, raster.get(), "cs_raster", nullptr, "splat-raster");
  gpu::ShaderModule composite = gpu::create_shader_from_file(ctx, "splat_tiles_composite.wgsl");
  WGPUBlendState blend = WGPU_BLEND_STATE_INIT;
  blend.color = {WGPUBlendOperation_Add, WGPUBlendFactor_One, WGPUBlendFactor_OneMinusSrcAlpha};
  blend.alpha = {WGPUBlendOperation_Add, WGPUBlendFactor_One, WGPUBlendFactor_OneMinusSrcAlpha};
  gpu::FullscreenPipelineDesc desc;
  desc.module = composite.get();
  desc.fragment_entry = "fs_composite";
  desc.format = p.color_format;
  desc.blend = &blend;
  desc.label = "splat-composite";
  p.tile_composite = gpu::create_fullscreen_pipeline(ctx, desc);
  p.no_depth = gpu::create_texture_2d(
      ctx, 1, 1, p.depth_format,
      WGPUTextureUsage_TextureBinding | WGPUTextureUsage_RenderAttachment, "splat-no-depth");
  p.no_depth_view = gpu::create_view(p.no_depth);
  p.tile_pipelines = true;
  ctx.check("creating the splat tile pipelines");
}

// The most (tile, splat) pairs one frame's buffers may hold on this device (a u32 a pair in
// one storage binding), or the set's lower bound (TilePairCounts::max_capacity).
uint64_t max_pair_capacity(const gpu::Context& ctx, const GpuSplats& s) {
  const uint64_t device = std::min<uint64_t>(
      {std::min<uint64_t>(ctx.limits.maxStorageBufferBindingSize, ctx.limits.maxBufferSize) / 4,
       uint64_t(UINT32_MAX / 2)});
  return s.pair_counts.max_capacity ? std::min<uint64_t>(device, s.pair_counts.max_capacity)
                                    : device;
}

// Room for each splat to touch four tiles on average, or 1.5 times the most pairs a frame
// wanted (a close-up's large splats touch many more), within the device's limit.
uint32_t wanted_pair_capacity(const gpu::Context& ctx, const GpuSplats& s) {
  const uint64_t want =
      std::max<uint64_t>({uint64_t(s.count) * 4, 1 << 16, uint64_t(s.pair_counts.needed) * 3 / 2});
  return uint32_t(std::min(want, max_pair_capacity(ctx, s)));
}

void ensure_tile_buffers(gpu::Context& ctx, const SplatPipelines& p, GpuSplats& s, uint32_t width,
                         uint32_t height) {
  if (s.tiles && s.tiles->width == width && s.tiles->height == height &&
      s.tiles->pair_capacity >= std::min<uint64_t>(s.pair_counts.needed, max_pair_capacity(ctx, s)))
    return;
  auto t = std::make_unique<TileBuffers>();
  t->width = width;
  t->height = height;
  t->tiles_x = (width + kTile - 1) / kTile;
  t->tiles_y = (height + kTile - 1) / kTile;
  if (uint64_t(t->tiles_x) * t->tiles_y > 65536)
    fail("splats: the tile rasterizer sorts tiles by 16 bits: {}x{} has too many tiles", width,
         height);
  t->pair_capacity = wanted_pair_capacity(ctx, s);
  // Room for the set's capacity: a composed set's count changes within it (compose_splats).
  const uint32_t blocks = (s.capacity + kScanBlock - 1) / kScanBlock;
  // Per splat its count (then offset) and its rectangle of tiles (splat_tiles.wgsl's rect_at).
  t->scan = gpu::create_buffer(ctx, (uint64_t(s.capacity) * 3 + blocks + 1) * 4,
                               WGPUBufferUsage_Storage, "splat-tile-scan");
  // The pairs kept, each tile's range, the pairs wanted (copied out: TilePairCounts).
  t->tile_data =
      gpu::create_buffer(ctx, (2 + 2 * uint64_t(t->tiles_x) * t->tiles_y) * 4,
                         WGPUBufferUsage_Storage | WGPUBufferUsage_CopySrc, "splat-tile-ranges");
  t->pixels = gpu::create_buffer(ctx, uint64_t(width) * height * 16, WGPUBufferUsage_Storage,
                                 "splat-tile-pixels");
  t->params =
      gpu::create_buffer(ctx, sizeof(TileParams), WGPUBufferUsage_Uniform | WGPUBufferUsage_CopyDst,
                         "splat-tile-params");
  t->sort = create_radix_sort_buffers(ctx, p.sort, t->pair_capacity, t->tile_data.get(), 0);
  const uint32_t r = radix_sort_result(kDepthKeyBits);
  t->binning = gpu::create_bind_group(
      ctx, p.tile_layout.get(),
      {gpu::bind_buffer(0, s.frame_uniforms.get()), gpu::bind_buffer(1, t->params.get()),
       gpu::bind_buffer(2, s.projected.get()), gpu::bind_buffer(3, s.sort.keys[r].get()),
       gpu::bind_buffer(4, s.sort.values[r].get()), gpu::bind_buffer(5, s.args.get()),
       gpu::bind_buffer(6, t->scan.get()), gpu::bind_buffer(7, t->sort.keys[0].get()),
       gpu::bind_buffer(8, t->sort.values[0].get()), gpu::bind_buffer(9, t->tile_data.get())},
      "splat-tiles");
  auto composite_layout = gpu::bind_group_layout_of(p.tile_composite);
  t->composite = gpu::create_bind_group(
      ctx, composite_layout.get(),
      {gpu::bind_buffer(0, s.frame_uniforms.get()), gpu::bind_buffer(1, t->pixels.get())},
      "splat-composite");
  s.tiles = std::move(t);
}

constexpr uint32_t kPairSlots = 3;  // frames whose pair totals may be on their way at once

// The frame's pair total into a free readback slot (none free: this frame goes unread; a later
// one tells the same).
void copy_pair_total(gpu::Context& ctx, WGPUCommandEncoder encoder, GpuSplats& s) {
  TilePairCounts& counts = s.pair_counts;
  if (counts.slots.empty()) {
    for (uint32_t i = 0; i < kPairSlots; ++i) {
      TilePairCounts::Slot slot;
      slot.readback = gpu::create_buffer(ctx, 4, WGPUBufferUsage_MapRead | WGPUBufferUsage_CopyDst,
                                         "splat-tile-pairs-readback");
      slot.state = std::make_shared<PairSlotState>();
      counts.slots.push_back(std::move(slot));
    }
  }
  for (auto& slot : counts.slots) {
    if (slot.state->phase != PairSlotState::Phase::Free) continue;
    const TileBuffers& t = *s.tiles;
    const uint64_t offset = (1 + 2 * uint64_t(t.tiles_x) * t.tiles_y) * 4;
    wgpuCommandEncoderCopyBufferToBuffer(encoder, t.tile_data.get(), offset, slot.readback.get(), 0,
                                         4);
    slot.capacity = t.pair_capacity;
    slot.state->phase = PairSlotState::Phase::Copied;
    return;
  }
}

// The tile rasterizer's passes after the projection and depth sort (see splats.hpp).
void add_tile_passes(gpu::RenderGraph& graph, SplatPipelines* pp, GpuSplats* sp,
                     const SplatPassTargets& targets, const std::string& projected, uint32_t width,
                     uint32_t height) {
  const bool depth_test = !targets.depth.empty();
  graph
      .add_pass(targets.name + "-bin", gpu::PassKind::Compute,
                [pp, sp, width, height, depth_test](gpu::PassContext& pc) {
                  gpu::Context& ctx = pc.gpu();
                  ensure_tile_buffers(ctx, *pp, *sp, width, height);
                  TileBuffers& t = *sp->tiles;
                  const uint32_t blocks = (sp->count + kScanBlock - 1) / kScanBlock;
                  const TileParams params{t.tiles_x, t.tiles_y,
                                          sp->count, t.pair_capacity,
                                          blocks,    depth_test ? 1u : 0u,
                                          0,         0};
                  gpu::write_buffer(ctx, t.params.get(), 0, params);
                  auto pass = pc.begin_compute_pass();
                  WGPUBindGroup g = t.binning.get();
                  const auto [sx, sy] = grid(sp->count, 256);
                  const auto [bx, by] = grid(uint64_t(blocks), 1);
                  gpu::dispatch(pass.get(), pp->tile_block_sums.get(), {g}, bx, by);
                  gpu::dispatch(pass.get(), pp->tile_scan_blocks.get(), {g}, 1);
                  gpu::dispatch(pass.get(), pp->tile_block_apply.get(), {g}, bx, by);
                  gpu::dispatch(pass.get(), pp->tile_emit.get(), {g}, sx, sy);
                  wgpuComputePassEncoderEnd(pass.get());
                  copy_pair_total(ctx, pc.encoder(), *sp);
                })
      .write(projected);
  graph
      .add_pass(targets.name + "-tile-sort", gpu::PassKind::Compute,
                [pp, sp](gpu::PassContext& pc) {
                  auto pass = pc.begin_compute_pass();
                  encode_radix_sort(pass.get(), pp->sort, sp->tiles->sort, 16);
                  wgpuComputePassEncoderEnd(pass.get());
                })
      .write(projected);
  auto raster = graph.add_pass(
      targets.name + "-raster", gpu::PassKind::Compute,
      [pp, sp, targets, depth_test](gpu::PassContext& pc) {
        gpu::Context& ctx = pc.gpu();
        TileBuffers& t = *sp->tiles;
        const uint32_t r = radix_sort_result(kDepthKeyBits);
        auto layout = gpu::bind_group_layout_of(pp->tile_raster);
        gpu::BindGroup group = gpu::create_bind_group(
            ctx, layout.get(),
            {gpu::bind_buffer(0, sp->frame_uniforms.get()), gpu::bind_buffer(1, t.params.get()),
             gpu::bind_buffer(2, sp->projected.get()), gpu::bind_buffer(3, sp->sort.keys[r].get()),
             gpu::bind_buffer(4, sp->sort.values[r].get()),
             gpu::bind_buffer(5, t.sort.values[0].get()), gpu::bind_buffer(6, t.tile_data.get()),
             gpu::bind_buffer(7, t.pixels.get()),
             gpu::bind_texture(8, depth_test ? pc.view(targets.depth) : pp->no_depth_view.get())},
            "splat-raster");
        auto pass = pc.begin_compute_pass();
        WGPUBindGroup g = t.binning.get();
        const auto [tx, ty] = grid(uint64_t(t.tiles_x) * t.tiles_y, 256);
        const auto [px, py] = grid(t.pair_capacity, 256);
        gpu::dispatch(pass.get(), pp->tile_clear_ranges.get(), {g}, tx, ty);
        gpu::dispatch(pass.get(), pp->tile_ranges.get(), {g}, px, py);
        gpu::dispatch(pass.get(), pp->tile_raster.get(), {group.get()}, t.tiles_x, t.tiles_y);
        wgpuComputePassEncoderEnd(pass.get());
      });
  raster.write(projected);
  if (depth_test) raster.read(targets.depth);
}

// The tile rasterizer's last pass: its pixels laid over the frame.
void add_tile_composite(gpu::RenderGraph& graph, SplatPipelines* pp, GpuSplats* sp,
                        const SplatPassTargets& targets, const std::string& projected) {
  graph
      .add_pass(targets.name + "-composite", gpu::PassKind::Render,
                [pp, sp, targets](gpu::PassContext& pc) {
                  gpu::draw_fullscreen(pc, pc.view(targets.color), pp->tile_composite.get(),
                                       {sp->tiles->composite.get()});
                })
      .read(projected)
      .write(targets.color);
}

std::string projected_name(const SplatPassTargets& targets) {
  return targets.name + "s-projected";
}

void import_projected(gpu::RenderGraph& graph, const GpuSplats& s,
                      const SplatPassTargets& targets) {
  graph.import_buffer(projected_name(targets), s.projected.get(),
                      {uint64_t(s.count) * kProjectedBytes, WGPUBufferUsage_Storage},
                      gpu::Access::Writable);
}

// Which of the tile rasterizer's passes add_splat_passes_to adds.
enum class TilePart { All, BeforeComposite };

}  // namespace

SplatRasterizer parse_splat_rasterizer(const std::string& name) {
  if (name == "quads") return SplatRasterizer::Quads;
  if (name == "tiles") return SplatRasterizer::Tiles;
  fail("unknown splat rasterizer '{}' (quads or tiles)", name);
}

const char* splat_rasterizer_name(SplatRasterizer rasterizer) {
  return rasterizer == SplatRasterizer::Tiles ? "tiles" : "quads";
}

SplatRasterizer default_splat_rasterizer(const gpu::Context& ctx) {
  // Tiles where the GPU has to blend much (on an H100, 6M splats of SH degree 3 at 1920x1080:
  // quads 82 ms a frame, bound by blending; tiles 5.8 ms). On a CPU adapter the tiles' compute
  // passes cost more than the rasterizer's blending: lavapipe, 200k splats of SH degree 3 at
  // 1280x720 (`stipple bench splats --count 200000 --sh 3 --size 1280x720 --frames 10`), quads
  // 382-744 ms a frame against tiles 984-1752 ms (wgpu and Dawn, 2 shared cores), and at a
  // close-up (--view close) 255-329 ms against 714-936 ms: quads there.
  return gpu::is_cpu_adapter(ctx.description) ? SplatRasterizer::Quads : SplatRasterizer::Tiles;
}

namespace {

void check_set(const io::SplatSet& set, std::string_view what) {
  const size_t n = set.size();
  if (set.scales.size() != n || set.rotations.size() != n || set.opacities.size() != n ||
      set.sh_dc.size() != n || set.sh_rest.size() != n * set.rest_count())
    fail("splats: {}'s arrays disagree on its size ({} positions)", what, n);
  if (set.sh_degree < 0 || set.sh_degree > 3)
    fail("splats: {} has SH degree {} (0 to 3 are drawn)", what, set.sh_degree);
}

// u32 words of f16 SH a splat for a degree, rounded up to whole vec4<u32>s: the projection
// loads them 16 bytes at a time (degree 3: 23 words, 24 with the padding).
uint32_t sh_stride_of(int sh_degree) {
  const uint32_t words = uint32_t(((sh_degree + 1) * (sh_degree + 1) - 1) * 3 + 1) / 2;
  return (words + 3) / 4 * 4;
}

// A set's splats in the GPU's layout, positions relative to `origin` (in the set's frame), SH as
// f16 at `sh_stride` words a splat (a lower degree's missing coefficients zero). `splats` and `sh`
// hold max(1, n) splats.
void pack_splats(const io::SplatSet& set, const glm::dvec3& origin, uint32_t sh_stride,
                 std::vector<GpuSplat>& splats, std::vector<uint32_t>& sh) {
  const size_t n = set.size();
  const size_t rest = set.rest_count();
  splats.assign(std::max<size_t>(1, n), GpuSplat{});
  sh.assign(std::max<size_t>(1, n * sh_stride), 0u);
  for (size_t i = 0; i < n; ++i) {
    GpuSplat& s = splats[i];
    const glm::dvec3 p = glm::dvec3(set.positions[i]) - origin;
    for (int k = 0; k < 3; ++k) {
      s.position[k] = float(p[k]);
      s.scale[k] = set.scales[i][k];
    }
    s.opacity = set.opacities[i];
    const glm::vec4& q = set.rotations[i];
    s.rot_xy = pack_half2(q.x, q.y);
    s.rot_zw = pack_half2(q.z, q.w);
    s.dc_rg = pack_half2(set.sh_dc[i].r, set.sh_dc[i].g);
    s.dc_b = pack_half2(set.sh_dc[i].b, 0.0f);
    // SH above degree 0 as f16, coefficient-major as in the set: half k * 3 + c.
    const glm::vec3* coefs = set.sh_rest.data() + i * rest;
    for (size_t h = 0; h < rest * 3; h += 2) {
      const float a = coefs[h / 3][int(h % 3)];
      const float b = h + 1 < rest * 3 ? coefs[(h + 1) / 3][int((h + 1) % 3)] : 0.0f;
      sh[i * sh_stride + h / 2] = pack_half2(a, b);
    }
  }
}

// A set's buffers for `capacity` splats of `sh_stride` words of SH, empty (the caller fills the
// splats and SH); throws where one would exceed a storage binding.
std::unique_ptr<GpuSplats> allocate_splats(gpu::Context& ctx, uint64_t count, uint64_t capacity,
                                           int sh_degree, WGPUBufferUsage extra_usage) {
  auto g = std::make_unique<GpuSplats>();
  g->count = uint32_t(count);
  g->sh_degree = sh_degree;
  g->sh_stride = sh_stride_of(sh_degree);
  const uint64_t limit =
      std::min<uint64_t>(ctx.limits.maxStorageBufferBindingSize, ctx.limits.maxBufferSize);
  const uint64_t room = std::max<uint64_t>(1, capacity);
  const uint64_t splat_bytes = room * sizeof(GpuSplat);
  const uint64_t sh_bytes = std::max<uint64_t>(4, room * g->sh_stride) * 4;  // one vec4 at least
  if (splat_bytes > limit || sh_bytes > limit || room * kProjectedBytes > limit ||
      room > UINT32_MAX)
    fail(
        "splats: {} splats of SH degree {} need {} bytes in one storage binding, over this "
        "device's limit of {}",
        count, sh_degree, std::max(splat_bytes, sh_bytes), limit);
  g->capacity = uint32_t(room);
  const WGPUBufferUsage usage = WGPUBufferUsage_Storage | extra_usage;
  g->splats = gpu::create_buffer(ctx, splat_bytes, usage, "splats");
  g->sh = gpu::create_buffer(ctx, sh_bytes, usage, "splat-sh");
  g->projected =
      gpu::create_buffer(ctx, room * kProjectedBytes, WGPUBufferUsage_Storage, "splats-projected");
  g->args = gpu::create_buffer(ctx, 16,
                               WGPUBufferUsage_Storage | WGPUBufferUsage_Indirect |
                                   WGPUBufferUsage_CopyDst | WGPUBufferUsage_CopySrc,
                               "splat-draw-args");
  g->frame_uniforms = gpu::create_buffer(
      ctx, sizeof(FrameUniforms), WGPUBufferUsage_Uniform | WGPUBufferUsage_CopyDst, "splat-frame");
  return g;
}

}  // namespace

GpuSplats upload_splats(gpu::Context& ctx, const io::SplatSet& set) {
  check_set(set, "the set");
  std::unique_ptr<GpuSplats> g =
      allocate_splats(ctx, set.size(), set.size(), set.sh_degree, WGPUBufferUsage_CopyDst);
  // Positions relative to their mean (float keeps its precision near the splats), the mean
  // through the set's transform in double.
  glm::dvec3 mean(0.0);
  for (const auto& p : set.positions) mean += glm::dvec3(p);
  if (set.size()) mean /= double(set.size());
  g->linear = glm::dmat3(set.transform);
  g->centre = g->linear * mean + glm::dvec3(set.transform[3]);
  std::vector<GpuSplat> splats;
  std::vector<uint32_t> sh;
  pack_splats(set, mean, g->sh_stride, splats, sh);
  gpu::write_buffer(ctx, g->splats.get(), 0, splats.data(), splats.size() * sizeof(GpuSplat));
  gpu::write_buffer(ctx, g->sh.get(), 0, sh.data(), sh.size() * 4);
  return std::move(*g);
}

void compose_splats(gpu::Context& ctx, SplatPartCache& cache, std::unique_ptr<GpuSplats>& into,
                    const std::vector<std::shared_ptr<const io::SplatSet>>& parts,
                    const glm::dmat4& transform) {
  std::erase_if(cache.parts, [](const auto& entry) { return entry.second.set.expired(); });
  uint64_t total = 0;
  // The set's SH degree only grows: parts are packed at its stride, so a list whose highest
  // degree drops (coarser tiles, or none) keeps the set and every uploaded part as they are.
  int degree = into ? into->sh_degree : 0;
  for (const auto& part : parts) {
    check_set(*part, "a part");
    total += part->size();
    degree = std::max(degree, part->sh_degree);
  }
  const uint32_t stride = sh_stride_of(degree);
  if (!into || into->capacity < total || into->sh_stride != stride) {
    // Half again what is needed, so that a growing selection does not remake the buffers (and
    // the tile rasterizer's, whose pair capacity it keeps) every few changes; within the limit.
    const uint64_t limit =
        std::min<uint64_t>(ctx.limits.maxStorageBufferBindingSize, ctx.limits.maxBufferSize) /
        std::max<uint64_t>(sizeof(GpuSplat), std::max(1u, stride) * 4);
    const uint64_t room = std::max(total, std::min(total + total / 2, limit));
    std::unique_ptr<GpuSplats> fresh =
        allocate_splats(ctx, total, room, degree, WGPUBufferUsage_CopyDst);
    if (into) fresh->pair_counts = std::move(into->pair_counts);
    into = std::move(fresh);
  }

  WGPUCommandEncoderDescriptor desc = WGPU_COMMAND_ENCODER_DESCRIPTOR_INIT;
  gpu::CommandEncoder encoder(wgpuDeviceCreateCommandEncoder(ctx.device.get(), &desc));
  std::vector<GpuSplat> packed;
  std::vector<uint32_t> sh;
  uint64_t at = 0;
  for (const auto& part : parts) {
    const uint32_t n = uint32_t(part->size());
    if (n == 0) continue;
    SplatPartCache::Part& entry = cache.parts[part.get()];
    if (!entry.splats || entry.sh_stride != stride) {
      pack_splats(*part, glm::dvec3(0.0), stride, packed, sh);
      entry.set = part;
      entry.sh_stride = stride;
      entry.splats = gpu::create_buffer(ctx, uint64_t(n) * sizeof(GpuSplat),
                                        WGPUBufferUsage_CopySrc, "splat-part", packed.data());
      entry.sh = stride ? gpu::create_buffer(ctx, uint64_t(n) * stride * 4, WGPUBufferUsage_CopySrc,
                                             "splat-part-sh", sh.data())
                        : gpu::Buffer{};
      cache.packed_splats += n;
    }
    wgpuCommandEncoderCopyBufferToBuffer(encoder.get(), entry.splats.get(), 0, into->splats.get(),
                                         at * sizeof(GpuSplat), uint64_t(n) * sizeof(GpuSplat));
    if (stride)
      wgpuCommandEncoderCopyBufferToBuffer(encoder.get(), entry.sh.get(), 0, into->sh.get(),
                                           at * stride * 4, uint64_t(n) * stride * 4);
    at += n;
  }
  gpu::CommandBuffer commands(wgpuCommandEncoderFinish(encoder.get(), nullptr));
  WGPUCommandBuffer raw = commands.get();
  wgpuQueueSubmit(ctx.queue.get(), 1, &raw);
  into->count = uint32_t(total);
  into->sh_degree = degree;
  into->linear = glm::dmat3(transform);
  into->centre = glm::dvec3(transform[3]);
}

SplatPipelines create_splat_pipelines(gpu::Context& ctx, WGPUTextureFormat color_format,
                                      WGPUTextureFormat depth_format) {
  static std::atomic<uint64_t> created{0};
  SplatPipelines p;
  p.id = ++created;
  p.color_format = color_format;
  p.depth_format = depth_format;
  gpu::ShaderModule project = gpu::create_shader_from_file(ctx, "splat_project.wgsl");
  p.project =
      gpu::create_compute_pipeline(ctx, project.get(), "cs_project", nullptr, "splat-project");
  gpu::ShaderModule draw = gpu::create_shader_from_file(ctx, "splat_draw.wgsl");
  p.draw_layout = make_draw_layout(ctx);
  p.draw_pipeline_layout = gpu::create_pipeline_layout(ctx, {p.draw_layout.get()});
  p.draw = make_draw_pipeline(ctx, draw.get(), p.draw_pipeline_layout.get(), color_format,
                              depth_format, true);
  p.draw_no_depth = make_draw_pipeline(ctx, draw.get(), p.draw_pipeline_layout.get(), color_format,
                                       depth_format, false);
  p.sort = create_radix_sort_pipelines(ctx);
  ctx.check("creating the splat pipelines");
  return p;
}

namespace {

void add_splat_passes_to(gpu::RenderGraph& graph, SplatPipelines& p, GpuSplats& s,
                         const Camera& camera, uint32_t width, uint32_t height,
                         const SplatPassTargets& targets, TilePart part) {
  if (s.count == 0) return;
  SplatPipelines* pp = &p;
  GpuSplats* sp = &s;
  auto frame = std::make_shared<FrameUniforms>(make_frame(s, camera, width, height));
  const std::string projected = projected_name(targets);
  import_projected(graph, s, targets);

  graph
      .add_pass(targets.name + "-project", gpu::PassKind::Compute,
                [pp, sp, frame](gpu::PassContext& pc) {
                  gpu::Context& ctx = pc.gpu();
                  if (sp->pipelines_id != pp->id) {
                    // Bind groups of other pipelines' (automatic) layouts do not fit these.
                    sp->sort = {};
                    sp->project_group = {};
                    sp->draw_group = {};
                    sp->tiles.reset();
                    sp->pipelines_id = pp->id;
                  }
                  if (!sp->sort.capacity)
                    sp->sort =
                        create_radix_sort_buffers(ctx, pp->sort, sp->capacity, sp->args.get(), 1);
                  ensure_groups(ctx, *pp, *sp);
                  gpu::write_buffer(ctx, sp->frame_uniforms.get(), 0, *frame);
                  const uint32_t args[4] = {4, 0, 0, 0};
                  gpu::write_buffer(ctx, sp->args.get(), 0, args, sizeof args);
                  const uint32_t groups = (sp->count + kProjectWorkgroup - 1) / kProjectWorkgroup;
                  const uint32_t x = std::min(groups, kMaxGroupsX);
                  const uint32_t y = (groups + x - 1) / x;
                  auto pass = pc.begin_compute_pass();
                  gpu::dispatch(pass.get(), pp->project.get(), {sp->project_group.get()}, x, y);
                  wgpuComputePassEncoderEnd(pass.get());
                })
      .write(projected);

  graph
      .add_pass(targets.name + "-sort", gpu::PassKind::Compute,
                [pp, sp](gpu::PassContext& pc) {
                  auto pass = pc.begin_compute_pass();
                  encode_radix_sort(pass.get(), pp->sort, sp->sort, kDepthKeyBits);
                  wgpuComputePassEncoderEnd(pass.get());
                })
      .write(projected);

  if (targets.rasterizer == SplatRasterizer::Tiles) {
    graph.add_prepare([pp](gpu::Context& ctx) { ensure_tile_pipelines(ctx, *pp); });
    add_tile_passes(graph, pp, sp, targets, projected, width, height);
    if (part == TilePart::All) add_tile_composite(graph, pp, sp, targets, projected);
    return;
  }
  const bool depth_test = !targets.depth.empty();
  auto draw = graph.add_pass(
      targets.name + "-draw", gpu::PassKind::Render,
      [pp, sp, targets, depth_test](gpu::PassContext& pc) {
        WGPURenderPassColorAttachment color = WGPU_RENDER_PASS_COLOR_ATTACHMENT_INIT;
        color.view = pc.view(targets.color);
        color.loadOp = WGPULoadOp_Load;
        color.storeOp = WGPUStoreOp_Store;
        WGPURenderPassDepthStencilAttachment depth = WGPU_RENDER_PASS_DEPTH_STENCIL_ATTACHMENT_INIT;
        WGPURenderPassDescriptor desc = WGPU_RENDER_PASS_DESCRIPTOR_INIT;
        desc.colorAttachmentCount = 1;
        desc.colorAttachments = &color;
        if (depth_test) {
          depth.view = pc.view(targets.depth);
          depth.depthReadOnly = true;
          depth.depthLoadOp = WGPULoadOp_Undefined;
          depth.depthStoreOp = WGPUStoreOp_Undefined;
          desc.depthStencilAttachment = &depth;
        }
        auto pass = pc.begin_render_pass(desc);
        wgpuRenderPassEncoderSetPipeline(pass.get(),
                                         depth_test ? pp->draw.get() : pp->draw_no_depth.get());
        gpu::set_bind_groups(pass.get(), {sp->draw_group.get()});
        wgpuRenderPassEncoderDrawIndirect(pass.get(), sp->args.get(), 0);
        wgpuRenderPassEncoderEnd(pass.get());
      });
  draw.read(projected).write(targets.color);
  if (depth_test) draw.read(targets.depth);
}

}  // namespace

void add_splat_passes(gpu::RenderGraph& graph, SplatPipelines& p, GpuSplats& s,
                      const Camera& camera, uint32_t width, uint32_t height,
                      const SplatPassTargets& targets) {
  add_splat_passes_to(graph, p, s, camera, width, height, targets, TilePart::All);
}

std::map<std::string, double> draw_splats(gpu::Context& ctx, SplatPipelines& p, GpuSplats& s,
                                          const Camera& camera, WGPUTexture color,
                                          WGPUTextureView color_view, uint32_t width,
                                          uint32_t height, WGPUTexture depth,
                                          WGPUTextureView depth_view, bool timed,
                                          SplatRasterizer rasterizer) {
  gpu::RenderGraph graph;
  graph.import_texture("color", color, color_view,
                       {width, height, p.color_format, WGPUTextureUsage_RenderAttachment},
                       gpu::Access::Writable);
  SplatPassTargets targets;
  targets.rasterizer = rasterizer;
  if (depth) {
    graph.import_texture("depth", depth, depth_view,
                         {width, height, p.depth_format, WGPUTextureUsage_RenderAttachment},
                         gpu::Access::ReadOnly);
  } else {
    targets.depth.clear();
  }
  // The tile rasterizer's frame in two submissions: all but the composite, drawn again (once its
  // pair count is known) when it wanted more pairs than the buffers held; then the composite
  // over `color`, which is drawn over only once.
  const bool tiles = rasterizer == SplatRasterizer::Tiles && s.count > 0;
  add_splat_passes_to(graph, p, s, camera, width, height, targets,
                      tiles ? TilePart::BeforeComposite : TilePart::All);
  graph.compile();
  gpu::PassTimer* timer = nullptr;
  if (timed) {
    if (!p.timer.enabled || p.timer.capacity < graph.plan().timed_passes)
      p.timer = gpu::create_pass_timer(ctx, graph.plan().timed_passes);
    if (p.timer.enabled) timer = &p.timer;
  }
  graph.execute(ctx, p.pool, timer);
  gpu::pool_end_frame(p.pool);
  std::map<std::string, double> times;
  if (tiles) {
    // The second is whole unless the device's limit stopped the growth.
    if (settle_tile_pairs(ctx, s, true)) {
      graph.execute(ctx, p.pool, timer);
      gpu::pool_end_frame(p.pool);
    }
    if (timer) times = graph.read_pass_times(ctx, *timer);
    gpu::RenderGraph composite;
    composite.import_texture("color", color, color_view,
                             {width, height, p.color_format, WGPUTextureUsage_RenderAttachment},
                             gpu::Access::Writable);
    import_projected(composite, s, targets);
    add_tile_composite(composite, &p, &s, targets, projected_name(targets));
    composite.execute(ctx, p.pool, timer);
    gpu::pool_end_frame(p.pool);
    if (timer) times.merge(composite.read_pass_times(ctx, *timer));
  }
  ctx.check("drawing splats");
  if (!timer || tiles) return times;
  return graph.read_pass_times(ctx, *timer);
}

bool settle_tile_pairs(gpu::Context& ctx, GpuSplats& s, bool wait) {
  TilePairCounts& counts = s.pair_counts;
  // Frames recorded since the last call have been submitted by now: map their slots.
  for (auto& slot : counts.slots) {
    if (slot.state->phase != PairSlotState::Phase::Copied) continue;
    gpu::map_async(slot.readback.get(), WGPUMapMode_Read, 4, slot.state);
  }
  auto mapping = [&counts] {
    return std::any_of(counts.slots.begin(), counts.slots.end(), [](const auto& slot) {
      return slot.state->phase == PairSlotState::Phase::Mapping;
    });
  };
  if (counts.slots.empty()) return false;
  gpu::settle_maps(ctx, wait, mapping, "the splat tile pairs");
  bool grew = false;
  const uint64_t limit = max_pair_capacity(ctx, s);
  for (auto& slot : counts.slots) {
    if (slot.state->phase == PairSlotState::Phase::Failed) {
      slot.state->phase = PairSlotState::Phase::Free;  // a cancelled map: that frame goes unread
      continue;
    }
    if (slot.state->phase != PairSlotState::Phase::Mapped) continue;
    uint32_t total = 0;
    const void* mapped = wgpuBufferGetConstMappedRange(slot.readback.get(), 0, 4);
    if (mapped) std::memcpy(&total, mapped, 4);
    wgpuBufferUnmap(slot.readback.get());
    slot.state->phase = PairSlotState::Phase::Free;
    counts.most = std::max(counts.most, total);
    if (total <= slot.capacity) continue;
    ++counts.overflowed_frames;
    if (total > limit && !counts.warned) {
      STIPPLE_WARN(
          "splats: a frame wants {} (tile, splat) pairs, over this device's limit of {}: the "
          "farthest splats' pairs are left out in such frames (the quads rasterizer draws them "
          "all)",
          total, limit);
      counts.warned = true;
    }
    if (total > counts.needed && total <= limit)
      STIPPLE_INFO(
          "splats: a frame wanted {} (tile, splat) pairs, {} a splat: the tile buffers grow", total,
          double(total) / std::max(1u, s.count));
    counts.needed = std::max(counts.needed, total);
    // The next frame's buffers hold at least this many (ensure_tile_buffers).
    grew = grew || slot.capacity < std::min<uint64_t>(total, limit);
  }
  return grew;
}

uint32_t tile_pair_capacity(const GpuSplats& s) {
  return s.tiles ? s.tiles->pair_capacity : 0;
}

uint32_t read_visible_count(gpu::Context& ctx, const GpuSplats& s) {
  auto bytes = gpu::read_buffer(ctx, s.args.get(), 4, 4);
  uint32_t n = 0;
  std::memcpy(&n, bytes.data(), 4);
  return n;
}

}  // namespace stipple::splats
