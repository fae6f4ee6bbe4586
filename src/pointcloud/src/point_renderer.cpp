#include "stipple/pointcloud/point_renderer.hpp"

#include <algorithm>
#include <cmath>
#include <cstring>

#include <glm/gtc/type_ptr.hpp>

#include "filter_uniforms.hpp"
#include "stipple/core/error.hpp"
#include "stipple/renderer/shader_preprocessor.hpp"

namespace stipple::pc {

SplatMode parse_splat_mode(const std::string& name) {
  if (name == "naive") return SplatMode::Naive;
  if (name == "blend") return SplatMode::Blend;
  fail("unknown splat mode '{}' (naive, blend)", name);
}

PointSizeMode parse_point_size_mode(const std::string& name) {
  if (name == "fixed") return PointSizeMode::Fixed;
  if (name == "attenuated") return PointSizeMode::Attenuated;
  if (name == "adaptive") return PointSizeMode::Adaptive;
  fail("unknown point size mode '{}' (fixed, attenuated, adaptive)", name);
}

namespace {

constexpr WGPUTextureFormat kAccumFormat = WGPUTextureFormat_RGBA16Float;
// The translucent pass's target (weighted blended OIT, point_draw.wgsl): weighted colour and
// weight sums. Half floats blend on every WebGPU device.
constexpr WGPUTextureFormat kOitAccumFormat = WGPUTextureFormat_RGBA16Float;
constexpr uint32_t kClodWorkgroup = 256;
// One CLOD dispatch covers a chunk: at most 65535 workgroups of 256 threads.
constexpr uint32_t kMaxChunkPoints = 8u << 20;

// Mirrors `Frame` in point_common.wgsl.
struct FrameUniforms {
  float view_proj[16];
  float viewport[2];
  float focal_px;
  float point_size;
  uint32_t size_mode;
  float size_scale;
  float max_point_px;
  float clod_k;
  uint32_t color_mode;
  uint32_t round_points;
  float blend_depth;
  float near_plane;
  float edl_radius;
  float edl_strength;
  uint32_t edl_enabled;
  uint32_t translucent;
  float ranges[4];
  float constant_color[4];
  float background[4];
  float palette[32][4];
  SkyUniforms sky;
};
static_assert(sizeof(FrameUniforms) == 800);

// Mirrors `Chunk` in point_common.wgsl.
struct ChunkUniforms {
  float offset[3];
  float spacing;
  float elevation;
  uint32_t count;
  float gps_range[2];
};
static_assert(sizeof(ChunkUniforms) == 32);

WGPUBindGroupLayout make_layout(gpu::Context& ctx,
                                std::initializer_list<WGPUBindGroupLayoutEntry> e) {
  WGPUBindGroupLayoutDescriptor desc = WGPU_BIND_GROUP_LAYOUT_DESCRIPTOR_INIT;
  desc.entryCount = e.size();
  desc.entries = e.begin();
  return wgpuDeviceCreateBindGroupLayout(ctx.device.get(), &desc);
}

WGPUBindGroupLayoutEntry buffer_entry(uint32_t binding, WGPUShaderStage visibility,
                                      WGPUBufferBindingType type, uint64_t min_size,
                                      bool dynamic = false) {
  WGPUBindGroupLayoutEntry e = WGPU_BIND_GROUP_LAYOUT_ENTRY_INIT;
  e.binding = binding;
  e.visibility = visibility;
  e.buffer.type = type;
  e.buffer.hasDynamicOffset = dynamic;
  e.buffer.minBindingSize = min_size;
  return e;
}

WGPUPipelineLayout make_pipeline_layout(gpu::Context& ctx,
                                        std::initializer_list<WGPUBindGroupLayout> layouts) {
  WGPUPipelineLayoutDescriptor desc = WGPU_PIPELINE_LAYOUT_DESCRIPTOR_INIT;
  desc.bindGroupLayoutCount = layouts.size();
  desc.bindGroupLayouts = layouts.begin();
  return wgpuDeviceCreatePipelineLayout(ctx.device.get(), &desc);
}

enum class DrawKind { Naive, SplatDepth, SplatAccum, Translucent };

gpu::RenderPipeline make_draw_pipeline(gpu::Context& ctx, const PointPipelines& p,
                                       WGPUShaderModule shader, bool indexed, DrawKind kind,
                                       WGPUTextureFormat color_format, bool extras = false) {
  WGPUBlendState additive = WGPU_BLEND_STATE_INIT;
  additive.color = {WGPUBlendOperation_Add, WGPUBlendFactor_One, WGPUBlendFactor_One};
  additive.alpha = {WGPUBlendOperation_Add, WGPUBlendFactor_One, WGPUBlendFactor_One};
  WGPUColorTargetState color_target = WGPU_COLOR_TARGET_STATE_INIT;
  color_target.format = gpu::native(color_format);
  color_target.writeMask = WGPUColorWriteMask_All;
  if (kind == DrawKind::SplatAccum || kind == DrawKind::Translucent) color_target.blend = &additive;
  WGPUFragmentState fragment = WGPU_FRAGMENT_STATE_INIT;
  fragment.module = shader;
  fragment.entryPoint = gpu::to_view(kind == DrawKind::Naive        ? "fs_naive"
                                     : kind == DrawKind::SplatDepth ? "fs_depth"
                                     : kind == DrawKind::SplatAccum ? "fs_accum"
                                                                    : "fs_translucent");
  fragment.targetCount = kind == DrawKind::SplatDepth ? 0 : 1;
  fragment.targets = &color_target;
  WGPUDepthStencilState depth = WGPU_DEPTH_STENCIL_STATE_INIT;
  depth.format = gpu::native(p.depth_format);
  // Reverse Z: nearer is greater. The accumulation pass tests against the pushed-back pre-pass
  // depth without writing, so every fragment within the tolerance adds up; the translucent pass
  // keeps what lies in front of the opaque points, without writing either.
  const bool read_only = kind == DrawKind::SplatAccum || kind == DrawKind::Translucent;
  depth.depthWriteEnabled = read_only ? WGPUOptionalBool_False : WGPUOptionalBool_True;
  depth.depthCompare =
      kind == DrawKind::SplatAccum ? WGPUCompareFunction_GreaterEqual : WGPUCompareFunction_Greater;

  WGPURenderPipelineDescriptor desc = WGPU_RENDER_PIPELINE_DESCRIPTOR_INIT;
  desc.label = gpu::to_view(kind == DrawKind::Naive        ? "points-naive"
                            : kind == DrawKind::SplatDepth ? "splat-depth"
                            : kind == DrawKind::SplatAccum ? "splat-accumulate"
                                                           : "points-translucent");
  desc.layout = extras ? (indexed ? p.indexed_extras_layout.get() : p.direct_extras_layout.get())
                       : (indexed ? p.indexed_layout.get() : p.direct_layout.get());
  desc.vertex.module = shader;
  desc.vertex.entryPoint =
      gpu::to_view(kind == DrawKind::Translucent ? "vs_translucent" : "vs_main");
  desc.primitive.topology = WGPUPrimitiveTopology_TriangleList;
  desc.primitive.cullMode = WGPUCullMode_None;
  desc.depthStencil = &depth;
  desc.multisample.count = 1;
  desc.multisample.mask = ~0u;
  desc.fragment = &fragment;
  return gpu::RenderPipeline(wgpuDeviceCreateRenderPipeline(ctx.device.get(), &desc));
}

}  // namespace

uint64_t max_gpu_chunk_points(const gpu::Context& ctx) {
  const uint64_t binding_limit = ctx.limits.maxStorageBufferBindingSize;
  const uint64_t buffer_limit = ctx.limits.maxBufferSize;
  return std::max<uint64_t>(
      1, std::min<uint64_t>({binding_limit / sizeof(PointChunk::Vertex),
                             buffer_limit / sizeof(PointChunk::Vertex), kMaxChunkPoints}));
}

void upload_chunk(gpu::Context& ctx, GpuPointCloud& gpu_cloud, const PointChunk& chunk) {
  // Chunks larger than one storage binding are split; the pieces share the origin.
  append_chunk_pieces(gpu_cloud, chunk, max_gpu_chunk_points(ctx),
                      [&](GpuPointCloud::Chunk& c, const PointChunk::Vertex* vertices) {
                        c.points =
                            gpu::create_buffer(ctx, uint64_t(c.count) * sizeof(PointChunk::Vertex),
                                               WGPUBufferUsage_Storage | WGPUBufferUsage_CopyDst,
                                               "point-chunk", vertices);
                        c.survivors = gpu::create_buffer(ctx, uint64_t(c.count) * 4,
                                                         WGPUBufferUsage_Storage, "clod-survivors");
                        c.points_buffer = c.points.get();
                        c.survivors_buffer = c.survivors.get();
                      });
}

void finish_upload(gpu::Context& ctx, GpuPointCloud& gpu_cloud) {
  gpu_cloud.clod_args_stride = std::max<uint32_t>(256, ctx.limits.minStorageBufferOffsetAlignment);
  gpu_cloud.clod_args = gpu::create_buffer(
      ctx, uint64_t(std::max<size_t>(1, gpu_cloud.chunks.size())) * gpu_cloud.clod_args_stride,
      WGPUBufferUsage_Storage | WGPUBufferUsage_Indirect | WGPUBufferUsage_CopyDst |
          WGPUBufferUsage_CopySrc,
      "clod-args");
  gpu_cloud.bind_groups_for = nullptr;
  ctx.check("uploading points");
}

bool upload_point_extras(gpu::Context& ctx, GpuPointCloud& gpu_cloud, const PointCloud& cloud) {
  // The pieces upload_chunk made: non-empty chunks in order, split at max_gpu_chunk_points.
  const uint64_t max_points = max_gpu_chunk_points(ctx);
  size_t piece = 0;
  bool all = true;
  for (const PointChunk& chunk : cloud.chunks) {
    const size_t n = chunk.vertices.size();
    const bool has = chunk.extras.size() == n;
    all &= has || n == 0;
    for (size_t first = 0; first < n; first += max_points, ++piece) {
      if (piece >= gpu_cloud.chunks.size())
        fail("upload_point_extras: the GPU cloud has fewer pieces than the cloud's chunks");
      GpuPointCloud::Chunk& c = gpu_cloud.chunks[piece];
      c.gps_origin = chunk.gps_origin;
      if (!has || c.extras) continue;
      c.extras = gpu::create_buffer(ctx, uint64_t(c.count) * sizeof(PointChunk::Extra),
                                    WGPUBufferUsage_Storage | WGPUBufferUsage_CopyDst,
                                    "point-extras", chunk.extras.data() + first);
    }
  }
  gpu_cloud.bind_groups_for = nullptr;  // the extras groups are made with the others
  ctx.check("uploading point extras");
  return all;
}

GpuPointCloud upload_point_cloud(gpu::Context& ctx, const PointCloud& cloud) {
  GpuPointCloud gpu_cloud;
  gpu_cloud.attributes = cloud.attributes;
  for (const PointChunk& chunk : cloud.chunks) upload_chunk(ctx, gpu_cloud, chunk);
  finish_upload(ctx, gpu_cloud);
  return gpu_cloud;
}

PointPipelines create_point_pipelines(gpu::Context& ctx, WGPUTextureFormat color_format,
                                      WGPUTextureFormat depth_format) {
  PointPipelines p;
  p.color_format = color_format;
  p.depth_format = depth_format;
  p.chunk_stride = std::max<uint32_t>(256, ctx.limits.minUniformBufferOffsetAlignment);
  const WGPUShaderStage all =
      WGPUShaderStage_Vertex | WGPUShaderStage_Fragment | WGPUShaderStage_Compute;
  p.frame_layout = gpu::BindGroupLayout(make_layout(
      ctx, {buffer_entry(0, all, WGPUBufferBindingType_Uniform, sizeof(FrameUniforms)),
            buffer_entry(1, all, WGPUBufferBindingType_Uniform, sizeof(ChunkUniforms), true),
            buffer_entry(2, all, WGPUBufferBindingType_Uniform, sizeof(detail::FilterUniforms)),
            buffer_entry(3, all, WGPUBufferBindingType_ReadOnlyStorage, 8)}));
  p.points_layout = gpu::BindGroupLayout(make_layout(
      ctx, {buffer_entry(0, WGPUShaderStage_Vertex | WGPUShaderStage_Compute,
                         WGPUBufferBindingType_ReadOnlyStorage, sizeof(PointChunk::Vertex))}));
  p.points_extras_layout = gpu::BindGroupLayout(make_layout(
      ctx, {buffer_entry(0, WGPUShaderStage_Vertex | WGPUShaderStage_Compute,
                         WGPUBufferBindingType_ReadOnlyStorage, sizeof(PointChunk::Vertex)),
            buffer_entry(1, WGPUShaderStage_Vertex, WGPUBufferBindingType_ReadOnlyStorage,
                         sizeof(PointChunk::Extra))}));
  p.survivors_layout = gpu::BindGroupLayout(make_layout(
      ctx, {buffer_entry(0, WGPUShaderStage_Vertex, WGPUBufferBindingType_ReadOnlyStorage, 4)}));
  p.clod_layout = gpu::BindGroupLayout(make_layout(
      ctx, {buffer_entry(0, WGPUShaderStage_Compute, WGPUBufferBindingType_Storage, 4),
            buffer_entry(1, WGPUShaderStage_Compute, WGPUBufferBindingType_Storage, 16)}));
  WGPUBindGroupLayoutEntry accumulated = WGPU_BIND_GROUP_LAYOUT_ENTRY_INIT;
  accumulated.binding = 0;
  accumulated.visibility = WGPUShaderStage_Fragment;
  accumulated.texture.sampleType = WGPUTextureSampleType_UnfilterableFloat;
  accumulated.texture.viewDimension = WGPUTextureViewDimension_2D;
  WGPUBindGroupLayoutEntry depth = accumulated;
  depth.binding = 1;
  depth.texture.sampleType = WGPUTextureSampleType_Depth;
  p.resolve_layout = gpu::BindGroupLayout(make_layout(ctx, {accumulated, depth}));

  p.direct_layout =
      gpu::PipelineLayout(make_pipeline_layout(ctx, {p.frame_layout.get(), p.points_layout.get()}));
  p.indexed_layout = gpu::PipelineLayout(make_pipeline_layout(
      ctx, {p.frame_layout.get(), p.points_layout.get(), p.survivors_layout.get()}));
  p.clod_pipeline_layout = gpu::PipelineLayout(make_pipeline_layout(
      ctx, {p.frame_layout.get(), p.points_layout.get(), p.clod_layout.get()}));
  p.resolve_pipeline_layout = gpu::PipelineLayout(
      make_pipeline_layout(ctx, {p.frame_layout.get(), p.resolve_layout.get()}));
  p.direct_extras_layout = gpu::PipelineLayout(
      make_pipeline_layout(ctx, {p.frame_layout.get(), p.points_extras_layout.get()}));
  p.indexed_extras_layout = gpu::PipelineLayout(make_pipeline_layout(
      ctx, {p.frame_layout.get(), p.points_extras_layout.get(), p.survivors_layout.get()}));

  gpu::ShaderModule shaders[2] = {gpu::create_shader_from_file(ctx, "points.wgsl"),
                                  gpu::create_shader_from_file(ctx, "points_clod.wgsl")};
  for (int indexed = 0; indexed < 2; ++indexed) {
    WGPUShaderModule s = shaders[indexed].get();
    p.naive_out[indexed] = make_draw_pipeline(ctx, p, s, indexed, DrawKind::Naive, color_format);
    p.naive_hdr[indexed] = make_draw_pipeline(ctx, p, s, indexed, DrawKind::Naive, kAccumFormat);
    p.splat_depth[indexed] =
        make_draw_pipeline(ctx, p, s, indexed, DrawKind::SplatDepth, kAccumFormat);
    p.splat_accum[indexed] =
        make_draw_pipeline(ctx, p, s, indexed, DrawKind::SplatAccum, kAccumFormat);
  }

  gpu::ShaderModule clod = gpu::create_shader_from_file(ctx, "clod.wgsl");
  p.clod = gpu::create_compute_pipeline(ctx, clod.get(), "cs_clod", p.clod_pipeline_layout.get(),
                                        "clod");

  gpu::ShaderModule resolve = gpu::create_shader_from_file(ctx, "splat_resolve.wgsl");
  p.resolve = gpu::create_fullscreen_pipeline(ctx, {.module = resolve.get(),
                                                    .vertex_entry = "vs_fullscreen",
                                                    .fragment_entry = "fs_resolve",
                                                    .layout = p.resolve_pipeline_layout.get(),
                                                    .format = color_format,
                                                    .label = "resolve"});

  p.frame_uniforms =
      gpu::create_buffer(ctx, sizeof(FrameUniforms),
                         WGPUBufferUsage_Uniform | WGPUBufferUsage_CopyDst, "frame-uniforms");
  p.filter_uniforms =
      gpu::create_buffer(ctx, sizeof(detail::FilterUniforms),
                         WGPUBufferUsage_Uniform | WGPUBufferUsage_CopyDst, "filter-uniforms");
  p.polygon_vertices =
      gpu::create_buffer(ctx, kMaxGpuPolygonVertices * 8,
                         WGPUBufferUsage_Storage | WGPUBufferUsage_CopyDst, "clip-polygons");
  ctx.check("creating the point pipelines");
  return p;
}

namespace {

void ensure_chunk_capacity(gpu::Context& ctx, PointPipelines& p, uint32_t chunks) {
  if (chunks <= p.chunk_capacity && p.frame_group) return;
  p.chunk_capacity = std::max<uint32_t>(chunks, 16);
  p.chunk_uniforms =
      gpu::create_buffer(ctx, uint64_t(p.chunk_capacity) * p.chunk_stride,
                         WGPUBufferUsage_Uniform | WGPUBufferUsage_CopyDst, "chunk-uniforms");
  p.frame_group = gpu::create_bind_group(
      ctx, p.frame_layout.get(),
      {gpu::bind_buffer(0, p.frame_uniforms.get(), 0, sizeof(FrameUniforms)),
       gpu::bind_buffer(1, p.chunk_uniforms.get(), 0, sizeof(ChunkUniforms)),
       gpu::bind_buffer(2, p.filter_uniforms.get(), 0, sizeof(detail::FilterUniforms)),
       gpu::bind_buffer(3, p.polygon_vertices.get(), 0, kMaxGpuPolygonVertices * 8)});
}

// The draw pipelines that bind the extras: only GPS-time and point-source filters need them.
void ensure_extras_pipelines(gpu::Context& ctx, PointPipelines& p) {
  if (p.extras_pipelines) return;
  gpu::ShaderModule shaders[2] = {gpu::create_shader_from_file(ctx, "points_extras.wgsl"),
                                  gpu::create_shader_from_file(ctx, "points_clod_extras.wgsl")};
  for (int indexed = 0; indexed < 2; ++indexed) {
    WGPUShaderModule s = shaders[indexed].get();
    p.naive_out_x[indexed] =
        make_draw_pipeline(ctx, p, s, indexed, DrawKind::Naive, p.color_format, true);
    p.naive_hdr_x[indexed] =
        make_draw_pipeline(ctx, p, s, indexed, DrawKind::Naive, kAccumFormat, true);
    p.splat_depth_x[indexed] =
        make_draw_pipeline(ctx, p, s, indexed, DrawKind::SplatDepth, kAccumFormat, true);
    p.splat_accum_x[indexed] =
        make_draw_pipeline(ctx, p, s, indexed, DrawKind::SplatAccum, kAccumFormat, true);
  }
  p.extras_pipelines = true;
  ctx.check("creating the filter pipelines");
}

// The translucent pass and its composite: only clouds with translucent points in the RGB mode
// need them (with `extras`, also the pass that binds the extras: GPS-time and point-source
// filters).
void ensure_translucent_pipelines(gpu::Context& ctx, PointPipelines& p, bool extras) {
  if (!p.translucent_pipelines) {
    gpu::ShaderModule shaders[2] = {gpu::create_shader_from_file(ctx, "points.wgsl"),
                                    gpu::create_shader_from_file(ctx, "points_clod.wgsl")};
    for (int indexed = 0; indexed < 2; ++indexed)
      p.translucent[indexed] = make_draw_pipeline(ctx, p, shaders[indexed].get(), indexed,
                                                  DrawKind::Translucent, kOitAccumFormat);
    WGPUBindGroupLayoutEntry accumulated = WGPU_BIND_GROUP_LAYOUT_ENTRY_INIT;
    accumulated.binding = 0;
    accumulated.visibility = WGPUShaderStage_Fragment;
    accumulated.texture.sampleType = WGPUTextureSampleType_UnfilterableFloat;
    accumulated.texture.viewDimension = WGPUTextureViewDimension_2D;
    p.composite_layout = gpu::BindGroupLayout(make_layout(ctx, {accumulated}));
    gpu::PipelineLayout layout(make_pipeline_layout(ctx, {p.composite_layout.get()}));
    // The average colour over the image by its coverage; the image's alpha stays.
    WGPUBlendState over = WGPU_BLEND_STATE_INIT;
    over.color = {WGPUBlendOperation_Add, WGPUBlendFactor_SrcAlpha,
                  WGPUBlendFactor_OneMinusSrcAlpha};
    over.alpha = {WGPUBlendOperation_Add, WGPUBlendFactor_Zero, WGPUBlendFactor_One};
    gpu::ShaderModule composite = gpu::create_shader_from_file(ctx, "oit_composite.wgsl");
    p.composite = gpu::create_fullscreen_pipeline(ctx, {.module = composite.get(),
                                                        .vertex_entry = "vs_fullscreen",
                                                        .fragment_entry = "fs_composite",
                                                        .layout = layout.get(),
                                                        .format = p.color_format,
                                                        .blend = &over,
                                                        .label = "points-composite"});
    p.translucent_pipelines = true;
  }
  if (extras && !p.translucent_extras_pipelines) {
    gpu::ShaderModule shaders[2] = {gpu::create_shader_from_file(ctx, "points_extras.wgsl"),
                                    gpu::create_shader_from_file(ctx, "points_clod_extras.wgsl")};
    for (int indexed = 0; indexed < 2; ++indexed)
      p.translucent_x[indexed] = make_draw_pipeline(ctx, p, shaders[indexed].get(), indexed,
                                                    DrawKind::Translucent, kOitAccumFormat, true);
    p.translucent_extras_pipelines = true;
  }
  ctx.check("creating the translucent point pipelines");
}

gpu::BindGroup buffer_group(
    gpu::Context& ctx, WGPUBindGroupLayout layout,
    std::initializer_list<std::pair<WGPUBuffer, std::pair<uint64_t, uint64_t>>> buffers) {
  std::vector<gpu::Binding> bindings;
  for (const auto& [buffer, range] : buffers)
    bindings.push_back(
        gpu::bind_buffer(uint32_t(bindings.size()), buffer, range.first, range.second));
  return gpu::create_bind_group(ctx, layout, bindings);
}

void ensure_cloud_groups(gpu::Context& ctx, const PointPipelines& p, GpuPointCloud& cloud) {
  if (cloud.bind_groups_for == &p) return;
  for (size_t i = 0; i < cloud.chunks.size(); ++i) {
    auto& c = cloud.chunks[i];
    uint64_t bytes = uint64_t(c.count) * sizeof(PointChunk::Vertex);
    const std::pair<uint64_t, uint64_t> survivors{c.survivors_offset, uint64_t(c.count) * 4};
    c.points_group =
        buffer_group(ctx, p.points_layout.get(), {{c.points_buffer, {c.points_offset, bytes}}});
    c.survivors_group =
        buffer_group(ctx, p.survivors_layout.get(), {{c.survivors_buffer, survivors}});
    c.clod_group =
        buffer_group(ctx, p.clod_layout.get(),
                     {{c.survivors_buffer, survivors},
                      {cloud.clod_args.get(), {uint64_t(i) * cloud.clod_args_stride, 16}}});
    c.points_extras_group = {};
    if (c.extras)
      c.points_extras_group =
          buffer_group(ctx, p.points_extras_layout.get(),
                       {{c.points_buffer, {c.points_offset, bytes}},
                        {c.extras.get(), {0, uint64_t(c.count) * sizeof(PointChunk::Extra)}}});
  }
  cloud.bind_groups_for = &p;
}

// Resolved per-frame state, computed when the passes are added.
struct FrameSetup {
  PointRenderSettings settings;
  FrameUniforms frame{};
  detail::FilterUniforms filter{};
  std::vector<float> polygon_vertices;  // x, y pairs
  glm::dvec2 elevation_range;
  bool clod = false;
  bool extras = false;       // GPS-time or point-source filters: the extras pipelines
  bool translucent = false;  // FrameUniforms::translucent: the translucent pass and composite
};

FrameSetup make_frame(const GpuPointCloud& cloud, const Camera& camera,
                      const PointRenderSettings& settings, uint32_t width, uint32_t height) {
  FrameSetup f;
  f.settings = settings;
  f.clod = settings.clod_k > 0.0f;
  FrameUniforms& u = f.frame;
  // Rotation-only view: the camera is at the origin of what the GPU sees.
  const glm::dmat4 view_proj_d = camera.projection(double(width) / height) * camera.view_rotation();
  glm::mat4 view_proj = glm::mat4(view_proj_d);
  std::memcpy(u.view_proj, glm::value_ptr(view_proj), sizeof(u.view_proj));
  u.sky = sky_uniforms(settings.sky, view_proj_d, width, height);
  u.viewport[0] = float(width);
  u.viewport[1] = float(height);
  u.focal_px = float(height / (2.0 * std::tan(camera.fov_y * 0.5)));
  u.point_size = settings.point_size > 0 ? settings.point_size : 2.0f;
  u.size_mode = uint32_t(settings.size_mode);
  u.size_scale = settings.size_scale;
  u.max_point_px = std::max(1.0f, settings.max_point_px);
  u.clod_k = std::max(0.0f, settings.clod_k);
  u.color_mode = uint32_t(resolve_color_mode(cloud.attributes, settings.color));
  u.round_points = settings.round ? 1u : 0u;
  u.blend_depth = std::max(0.0f, settings.blend_depth);
  u.near_plane = float(camera.near_plane);
  u.edl_radius = settings.edl_radius;
  u.edl_strength = settings.edl_strength;
  u.edl_enabled = settings.edl ? 1u : 0u;
  // Alpha counts in the RGB mode of clouds that have translucent points; other modes replace
  // the colour and draw every point opaque.
  f.translucent = cloud.attributes.has_translucent && ColorMode(u.color_mode) == ColorMode::Rgb;
  u.translucent = f.translucent ? 1u : 0u;
  glm::dvec2 e = settings.elevation_range.y > settings.elevation_range.x
                     ? settings.elevation_range
                     : cloud.attributes.elevation_percentiles;
  glm::dvec2 in = settings.intensity_range.y > settings.intensity_range.x
                      ? settings.intensity_range
                      : cloud.attributes.intensity_percentiles;
  f.elevation_range = e;
  u.ranges[0] = float(e.x);
  u.ranges[1] = float(1.0 / std::max(e.y - e.x, 1e-9));
  u.ranges[2] = float(in.x);
  u.ranges[3] = float(1.0 / std::max(in.y - in.x, 1e-9));
  for (int c = 0; c < 3; ++c) {
    u.constant_color[c] = settings.constant_color[c];
    u.background[c] = settings.background[c];
  }
  u.constant_color[3] = u.background[3] = 1.0f;
  const auto& palette = classification_palette();
  for (size_t i = 0; i < palette.size(); ++i) {
    for (int c = 0; c < 3; ++c) u.palette[i][c] = palette[i][c];
    u.palette[i][3] = 1.0f;
  }
  f.extras = settings.filter.needs_extras();
  f.polygon_vertices =
      make_filter_uniforms(settings.filter, settings.clip, settings.highlight, camera, f.filter);
  return f;
}

// Uploads the frame and chunk uniforms (queue writes land before the graph's command buffer).
void write_uniforms(gpu::Context& ctx, PointPipelines& p, const GpuPointCloud& cloud,
                    const Camera& camera, const FrameSetup& f) {
  ensure_chunk_capacity(ctx, p, uint32_t(cloud.chunks.size()));
  gpu::write_buffer(ctx, p.frame_uniforms.get(), 0, f.frame);
  gpu::write_buffer(ctx, p.filter_uniforms.get(), 0, f.filter);
  if (!f.polygon_vertices.empty())
    gpu::write_buffer(ctx, p.polygon_vertices.get(), 0, f.polygon_vertices.data(),
                      f.polygon_vertices.size() * sizeof(float));
  const glm::dvec2 gps =
      f.settings.filter.gps_time.value_or(glm::dvec2(-detail::kFloatHuge, detail::kFloatHuge));
  // Camera-relative offsets: subtract in double, then cast (seed 000, eq. 5).
  std::vector<uint8_t> bytes(size_t(p.chunk_stride) * std::max<size_t>(1, cloud.chunks.size()));
  for (size_t i = 0; i < cloud.chunks.size(); ++i) {
    const auto& c = cloud.chunks[i];
    glm::dvec3 rel = c.origin - camera.position;
    ChunkUniforms u{};
    u.offset[0] = float(rel.x);
    u.offset[1] = float(rel.y);
    u.offset[2] = float(rel.z);
    u.spacing = float(c.spacing);
    u.elevation = float(c.origin.y - f.elevation_range.x);
    u.count = c.count;
    // The GPS-time range relative to the chunk's own origin, in double, then cast.
    u.gps_range[0] = detail::clamp_float(gps.x - c.gps_origin);
    u.gps_range[1] = detail::clamp_float(gps.y - c.gps_origin);
    std::memcpy(bytes.data() + i * p.chunk_stride, &u, sizeof(u));
  }
  gpu::write_buffer(ctx, p.chunk_uniforms.get(), 0, bytes.data(), bytes.size());
}

WGPURenderPassColorAttachment color_attachment(WGPUTextureView view, WGPULoadOp load,
                                               glm::vec4 clear) {
  WGPURenderPassColorAttachment a = WGPU_RENDER_PASS_COLOR_ATTACHMENT_INIT;
  a.view = view;
  a.loadOp = load;
  a.storeOp = WGPUStoreOp_Store;
  a.clearValue = {clear.r, clear.g, clear.b, clear.a};
  return a;
}

WGPURenderPassDepthStencilAttachment depth_attachment(WGPUTextureView view, bool clear,
                                                      bool store) {
  WGPURenderPassDepthStencilAttachment a = WGPU_RENDER_PASS_DEPTH_STENCIL_ATTACHMENT_INIT;
  a.view = view;
  a.depthLoadOp = clear ? WGPULoadOp_Clear : WGPULoadOp_Load;
  a.depthStoreOp = store ? WGPUStoreOp_Store : WGPUStoreOp_Discard;
  a.depthClearValue = 0.0f;  // reverse Z: far is 0
  return a;
}

// Draws every chunk with `pipeline` (index 1: the CLOD survivors, indirect); with `extras`
// (a GPS-time or point-source filter), chunks that have extras use `extras_pipelines`.
void draw_chunks(WGPURenderPassEncoder pass, const PointPipelines& p, const GpuPointCloud& cloud,
                 const std::array<gpu::RenderPipeline, 2>& pipelines, bool clod,
                 const std::array<gpu::RenderPipeline, 2>* extras_pipelines = nullptr) {
  WGPURenderPipeline bound = nullptr;
  for (size_t i = 0; i < cloud.chunks.size(); ++i) {
    const auto& c = cloud.chunks[i];
    const bool with_extras = extras_pipelines && c.points_extras_group;
    WGPURenderPipeline pipeline = (with_extras ? *extras_pipelines : pipelines)[clod ? 1 : 0].get();
    if (pipeline != bound) wgpuRenderPassEncoderSetPipeline(pass, bound = pipeline);
    WGPUBindGroup points = with_extras ? c.points_extras_group.get() : c.points_group.get();
    const uint32_t offset[1] = {uint32_t(i) * p.chunk_stride};
    if (clod) {
      gpu::set_bind_groups(pass, {{p.frame_group.get(), offset}, points, c.survivors_group.get()});
      wgpuRenderPassEncoderDrawIndirect(pass, cloud.clod_args.get(),
                                        uint64_t(i) * cloud.clod_args_stride);
    } else {
      gpu::set_bind_groups(pass, {{p.frame_group.get(), offset}, points});
      wgpuRenderPassEncoderDraw(pass, c.count * 6, 1, 0, 0);
    }
  }
}

// A pass that adds the chunks drawn with `pipelines` into `target` (cleared to 0) where they lie
// within the depth the earlier pass wrote (read only): Botsch et al.'s accumulation and the
// translucent points' weighted sums alike.
void draw_chunks_additive(gpu::PassContext& pc, WGPUTextureView target, WGPUTextureView depth_view,
                          const PointPipelines& p, const GpuPointCloud& cloud,
                          const std::array<gpu::RenderPipeline, 2>& pipelines, bool clod,
                          const std::array<gpu::RenderPipeline, 2>* extras_pipelines) {
  WGPURenderPassColorAttachment color = color_attachment(target, WGPULoadOp_Clear, glm::vec4(0.0f));
  WGPURenderPassDepthStencilAttachment depth = depth_attachment(depth_view, false, true);
  depth.depthReadOnly = true;
  depth.depthLoadOp = WGPULoadOp_Undefined;
  depth.depthStoreOp = WGPUStoreOp_Undefined;
  WGPURenderPassDescriptor desc = WGPU_RENDER_PASS_DESCRIPTOR_INIT;
  desc.colorAttachmentCount = 1;
  desc.colorAttachments = &color;
  desc.depthStencilAttachment = &depth;
  gpu::RenderPassEncoder pass = pc.begin_render_pass(desc);
  draw_chunks(pass.get(), p, cloud, pipelines, clod, extras_pipelines);
  wgpuRenderPassEncoderEnd(pass.get());
}

}  // namespace

std::vector<std::string> point_pass_names(const PointRenderSettings& s, bool translucent) {
  std::vector<std::string> names;
  if (s.clod_k > 0) names.push_back("clod");
  if (s.splat == SplatMode::Naive) {
    names.push_back("points");
  } else {
    names.push_back("splat-depth");
    names.push_back("splat-accumulate");
  }
  if (s.splat == SplatMode::Blend || s.edl || s.sky.enabled) names.push_back("resolve");
  if (translucent) {
    names.push_back("points-translucent");
    names.push_back("points-composite");
  }
  return names;
}

void add_point_cloud_passes(gpu::RenderGraph& graph, PointPipelines& p, GpuPointCloud& cloud,
                            const Camera& camera, const PointRenderSettings& settings,
                            uint32_t width, uint32_t height, const PointPassTargets& targets) {
  auto setup = std::make_shared<FrameSetup>(make_frame(cloud, camera, settings, width, height));
  const bool clod = setup->clod;
  const bool blend = settings.splat == SplatMode::Blend;
  // The sky is drawn by the resolve, where nothing was drawn.
  const bool resolve = blend || settings.edl || settings.sky.enabled;
  const glm::vec3 bg = settings.background;
  PointPipelines* pp = &p;
  GpuPointCloud* cp = &cloud;
  const bool translucent = setup->translucent;
  // Pipelines made on first use, before any pass runs (their validation may yield).
  graph.add_prepare([pp, setup](gpu::Context& ctx) {
    if (setup->extras) ensure_extras_pipelines(ctx, *pp);
    if (setup->translucent) ensure_translucent_pipelines(ctx, *pp, setup->extras);
  });
  // The first pass that runs uploads the uniforms and makes the cloud's bind groups.
  auto prepare = [pp, cp, camera, setup](gpu::Context& ctx) {
    ensure_cloud_groups(ctx, *pp, *cp);
    write_uniforms(ctx, *pp, *cp, camera, *setup);
  };
  const bool extras = setup->extras;

  if (clod) {
    graph.import_buffer(
        "clod-args", cloud.clod_args.get(),
        {uint64_t(std::max<size_t>(1, cloud.chunks.size())) * cloud.clod_args_stride,
         WGPUBufferUsage_Storage | WGPUBufferUsage_Indirect},
        gpu::Access::Writable);
    auto execute = [pp, cp, prepare](gpu::PassContext& pc) {
      gpu::Context& ctx = pc.gpu();
      prepare(ctx);
      // Reset every chunk's arguments to {0, 1, 0, 0}.
      std::vector<uint32_t> args(cp->chunks.size() * cp->clod_args_stride / 4, 0);
      for (size_t i = 0; i < cp->chunks.size(); ++i) args[i * cp->clod_args_stride / 4 + 1] = 1;
      if (!args.empty())
        gpu::write_buffer(ctx, cp->clod_args.get(), 0, args.data(), args.size() * 4);
      gpu::ComputePassEncoder pass = pc.begin_compute_pass();
      for (size_t i = 0; i < cp->chunks.size(); ++i) {
        const auto& c = cp->chunks[i];
        const uint32_t offset[1] = {uint32_t(i) * pp->chunk_stride};
        gpu::dispatch(pass.get(), pp->clod.get(),
                      {{pp->frame_group.get(), offset}, c.points_group.get(), c.clod_group.get()},
                      (c.count + kClodWorkgroup - 1) / kClodWorkgroup);
      }
      wgpuComputePassEncoderEnd(pass.get());
    };
    graph.add_pass("clod", gpu::PassKind::Compute, std::move(execute)).write("clod-args");
  }

  // Depth: the caller's, or a transient that the resolve can read.
  const WGPUTextureUsage depth_usage =
      WGPUTextureUsage_RenderAttachment |
      (resolve || targets.keep_depth ? WGPUTextureUsage_TextureBinding : 0);
  auto declare_depth = [&](gpu::PassBuilder& pass) {
    if (targets.create_depth)
      pass.create_texture(targets.depth, {width, height, p.depth_format, depth_usage});
    else
      pass.write(targets.depth);
  };
  const std::string accum = "point-accumulation";
  const gpu::TextureDesc accum_desc{
      width, height, kAccumFormat,
      WGPUTextureUsage_RenderAttachment | WGPUTextureUsage_TextureBinding};
  // A transient depth buffer is dropped after its last pass; an imported one is kept.
  const bool keep_depth = resolve || translucent || !targets.create_depth || targets.keep_depth;

  if (!blend) {
    // Naive: straight into the output, or into the accumulation texture for the EDL resolve.
    auto execute = [pp, cp, prepare, setup, targets, resolve, clod, keep_depth, bg, accum,
                    extras](gpu::PassContext& pc) {
      if (!clod) prepare(pc.gpu());
      WGPURenderPassColorAttachment color =
          resolve ? color_attachment(pc.view(accum), WGPULoadOp_Clear, glm::vec4(0.0f))
                  : color_attachment(pc.view(targets.color), WGPULoadOp_Clear, glm::vec4(bg, 1));
      WGPURenderPassDepthStencilAttachment depth =
          depth_attachment(pc.view(targets.depth), true, keep_depth);
      WGPURenderPassDescriptor desc = WGPU_RENDER_PASS_DESCRIPTOR_INIT;
      desc.colorAttachmentCount = 1;
      desc.colorAttachments = &color;
      desc.depthStencilAttachment = &depth;
      gpu::RenderPassEncoder pass = pc.begin_render_pass(desc);
      draw_chunks(pass.get(), *pp, *cp, resolve ? pp->naive_hdr : pp->naive_out, clod,
                  extras ? (resolve ? &pp->naive_hdr_x : &pp->naive_out_x) : nullptr);
      wgpuRenderPassEncoderEnd(pass.get());
    };
    auto pass = graph.add_pass("points", gpu::PassKind::Render, std::move(execute));
    if (clod) pass.read("clod-args");
    if (resolve)
      pass.create_texture(accum, accum_desc);
    else
      pass.write(targets.color);
    declare_depth(pass);
  } else {
    auto depth_pass = [pp, cp, prepare, targets, clod, extras](gpu::PassContext& pc) {
      if (!clod) prepare(pc.gpu());
      WGPURenderPassDepthStencilAttachment depth =
          depth_attachment(pc.view(targets.depth), true, true);
      WGPURenderPassDescriptor desc = WGPU_RENDER_PASS_DESCRIPTOR_INIT;
      desc.depthStencilAttachment = &depth;
      gpu::RenderPassEncoder pass = pc.begin_render_pass(desc);
      draw_chunks(pass.get(), *pp, *cp, pp->splat_depth, clod,
                  extras ? &pp->splat_depth_x : nullptr);
      wgpuRenderPassEncoderEnd(pass.get());
    };
    auto pass = graph.add_pass("splat-depth", gpu::PassKind::Render, std::move(depth_pass));
    if (clod) pass.read("clod-args");
    declare_depth(pass);

    auto accum_pass = [pp, cp, targets, clod, accum, extras](gpu::PassContext& pc) {
      draw_chunks_additive(pc, pc.view(accum), pc.view(targets.depth), *pp, *cp, pp->splat_accum,
                           clod, extras ? &pp->splat_accum_x : nullptr);
    };
    auto acc = graph.add_pass("splat-accumulate", gpu::PassKind::Render, std::move(accum_pass));
    if (clod) acc.read("clod-args");
    acc.read(targets.depth).create_texture(accum, accum_desc);
  }

  if (resolve) {
    auto execute = [pp, targets, accum](gpu::PassContext& pc) {
      gpu::Context& ctx = pc.gpu();
      gpu::BindGroup group = gpu::create_bind_group(
          ctx, pp->resolve_layout.get(),
          {gpu::bind_texture(0, pc.view(accum)), gpu::bind_texture(1, pc.view(targets.depth))});
      const uint32_t offset[1] = {0};
      gpu::draw_fullscreen(pc, pc.view(targets.color), pp->resolve.get(),
                           {{pp->frame_group.get(), offset}, group.get()}, WGPUColor{0, 0, 0, 1});
    };
    graph.add_pass("resolve", gpu::PassKind::Render, std::move(execute))
        .read(accum)
        .read(targets.depth)
        .write(targets.color);
  }

  if (translucent) {
    // Weighted blended OIT (point_draw.wgsl): the translucent points in front of the opaque
    // depth, then their average laid over the image by their coverage.
    const std::string oit_accum = "oit-accumulation";
    auto translucent_pass = [pp, cp, targets, clod, extras, oit_accum](gpu::PassContext& pc) {
      draw_chunks_additive(pc, pc.view(oit_accum), pc.view(targets.depth), *pp, *cp,
                           pp->translucent, clod, extras ? &pp->translucent_x : nullptr);
    };
    auto oit =
        graph.add_pass("points-translucent", gpu::PassKind::Render, std::move(translucent_pass));
    if (clod) oit.read("clod-args");
    const WGPUTextureUsage usage =
        WGPUTextureUsage_RenderAttachment | WGPUTextureUsage_TextureBinding;
    oit.read(targets.depth).create_texture(oit_accum, {width, height, kOitAccumFormat, usage});

    auto composite = [pp, targets, oit_accum](gpu::PassContext& pc) {
      gpu::BindGroup group = gpu::create_bind_group(pc.gpu(), pp->composite_layout.get(),
                                                    {gpu::bind_texture(0, pc.view(oit_accum))});
      gpu::draw_fullscreen(pc, pc.view(targets.color), pp->composite.get(), {group.get()});
    };
    graph.add_pass("points-composite", gpu::PassKind::Render, std::move(composite))
        .read(oit_accum)
        .write(targets.color);
  }
}

void draw_points(gpu::Context& ctx, PointPipelines& p, GpuPointCloud& cloud, const Camera& camera,
                 const PointRenderSettings& settings, WGPUTexture color, WGPUTextureView color_view,
                 uint32_t width, uint32_t height) {
  gpu::RenderGraph graph;
  graph.import_texture("color", color, color_view,
                       {width, height, p.color_format, WGPUTextureUsage_RenderAttachment},
                       gpu::Access::Writable);
  add_point_cloud_passes(graph, p, cloud, camera, settings, width, height);
  graph.compile();
  if (!p.timer.enabled || p.timer.capacity < graph.plan().timed_passes)
    p.timer = gpu::create_pass_timer(ctx, graph.plan().timed_passes);
  graph.execute(ctx, p.pool, &p.timer);
  gpu::pool_end_frame(p.pool);
  ctx.check("drawing points");
}

float auto_point_size(const Aabb& bounds, uint64_t point_count, const Camera& camera,
                      uint32_t height) {
  if (point_count == 0 || bounds.empty()) return 2.0f;
  glm::dvec3 size = bounds.size();
  // Every point at one location (framed_extent): no spacing to follow; a marker that shows.
  if (std::max({size.x, size.y, size.z}) < kDegenerateExtent) return 8.0f;
  // Airborne data covers the horizontal plane (x, -z in world space).
  double area = std::max(size.x * size.z, 1e-9);
  double spacing = std::sqrt(area / double(point_count));
  double distance = std::max(glm::length(bounds.center() - camera.position), 1e-6);
  double focal = height / (2.0 * std::tan(camera.fov_y * 0.5));
  double pixels = spacing * focal / distance;
  return float(std::clamp(pixels * 1.6, 1.0, 12.0));
}

float auto_point_size(const PointCloud& cloud, const Camera& camera, uint32_t height) {
  return auto_point_size(cloud.world_bounds, cloud.point_count, camera, height);
}

float clod_random(const glm::vec3& local) {
  float v = std::cos(local.x + local.y + local.z) * 43758.5453f;
  return v - std::floor(v);
}

bool clod_keep(const glm::vec3& local, const glm::vec3& chunk_offset, float spacing, float k) {
  if (k <= 0.0f) return true;
  float d = glm::length(local + chunk_offset);
  return clod_random(local) < spacing / (d * k);
}

uint64_t clod_survivors_cpu(const PointCloud& cloud, const Camera& camera, float k) {
  uint64_t n = 0;
  for (const PointChunk& chunk : cloud.chunks) {
    glm::vec3 offset(chunk.origin - camera.position);
    float spacing = float(chunk.spacing > 0 ? chunk.spacing : 1.0);
    for (const auto& v : chunk.vertices) n += clod_keep({v.x, v.y, v.z}, offset, spacing, k);
  }
  return n;
}

uint64_t read_clod_survivors(gpu::Context& ctx, const GpuPointCloud& cloud) {
  if (cloud.chunks.empty()) return 0;
  auto bytes = gpu::read_buffer(ctx, cloud.clod_args.get(), 0,
                                uint64_t(cloud.chunks.size()) * cloud.clod_args_stride);
  uint64_t n = 0;
  for (size_t i = 0; i < cloud.chunks.size(); ++i) {
    uint32_t vertices;
    std::memcpy(&vertices, bytes.data() + i * cloud.clod_args_stride, 4);
    n += vertices / 6;
  }
  return n;
}

float compute_point_size(const PointRenderSettings& settings) {
  return settings.size_mode == PointSizeMode::Fixed ? std::max(1.0f, settings.point_size) : 1.0f;
}

PointShading point_shading(const PointRenderSettings& settings, const CloudAttributes& a) {
  PointShading s;
  s.mode = settings.color;
  s.elevation_range = settings.elevation_range.y > settings.elevation_range.x
                          ? settings.elevation_range
                          : a.elevation_percentiles;
  s.intensity_range = settings.intensity_range.y > settings.intensity_range.x
                          ? settings.intensity_range
                          : a.intensity_percentiles;
  s.constant_color = settings.constant_color;
  return s;
}

}  // namespace stipple::pc
