#include "pointcloud/point_renderer.hpp"

#include <algorithm>
#include <cmath>
#include <cstring>

#include <glm/gtc/type_ptr.hpp>

#include "core/error.hpp"
#include "renderer/shader_preprocessor.hpp"

namespace stipple::pc {

GpuPointCloud upload_point_cloud(gpu::Context& ctx, const PointCloud& cloud) {
  GpuPointCloud gpu_cloud;
  for (const PointChunk& chunk : cloud.chunks) {
    if (chunk.vertices.empty()) continue;
    GpuPointCloud::Chunk c;
    c.count = uint32_t(chunk.vertices.size());
    c.origin = chunk.origin;
    c.vertices = gpu::create_buffer(ctx, chunk.vertices.size() * sizeof(PointChunk::Vertex),
                                    WGPUBufferUsage_Vertex, "point-chunk", chunk.vertices.data());
    gpu_cloud.point_count += c.count;
    gpu_cloud.chunks.push_back(std::move(c));
  }
  ctx.check("uploading points");
  return gpu_cloud;
}

namespace {
struct FrameUniforms {
  float view_proj[16];
  float viewport[2];
  float point_size;
  uint32_t round_points;
};
static_assert(sizeof(FrameUniforms) == 80);
}  // namespace

PointPipeline create_point_pipeline(gpu::Context& ctx, WGPUTextureFormat color_format,
                                    WGPUTextureFormat depth_format) {
  PointPipeline p;
  p.shader = gpu::create_shader_from_file(ctx, "points.wgsl");
  p.chunk_stride = std::max<uint32_t>(16, ctx.limits.minUniformBufferOffsetAlignment);

  WGPUBindGroupLayoutEntry entries[2] = {WGPU_BIND_GROUP_LAYOUT_ENTRY_INIT,
                                         WGPU_BIND_GROUP_LAYOUT_ENTRY_INIT};
  entries[0].binding = 0;
  entries[0].visibility = WGPUShaderStage_Vertex | WGPUShaderStage_Fragment;
  entries[0].buffer.type = WGPUBufferBindingType_Uniform;
  entries[0].buffer.minBindingSize = sizeof(FrameUniforms);
  entries[1].binding = 1;
  entries[1].visibility = WGPUShaderStage_Vertex;
  entries[1].buffer.type = WGPUBufferBindingType_Uniform;
  entries[1].buffer.hasDynamicOffset = true;
  entries[1].buffer.minBindingSize = 16;
  WGPUBindGroupLayoutDescriptor layout_desc = WGPU_BIND_GROUP_LAYOUT_DESCRIPTOR_INIT;
  layout_desc.entryCount = 2;
  layout_desc.entries = entries;
  p.layout = gpu::BindGroupLayout(wgpuDeviceCreateBindGroupLayout(ctx.device.get(), &layout_desc));
  WGPUBindGroupLayout layouts[] = {p.layout.get()};
  WGPUPipelineLayoutDescriptor pl_desc = WGPU_PIPELINE_LAYOUT_DESCRIPTOR_INIT;
  pl_desc.bindGroupLayoutCount = 1;
  pl_desc.bindGroupLayouts = layouts;
  p.pipeline_layout =
      gpu::PipelineLayout(wgpuDeviceCreatePipelineLayout(ctx.device.get(), &pl_desc));

  WGPUVertexAttribute attributes[2] = {WGPU_VERTEX_ATTRIBUTE_INIT, WGPU_VERTEX_ATTRIBUTE_INIT};
  attributes[0].format = WGPUVertexFormat_Float32x3;
  attributes[0].offset = 0;
  attributes[0].shaderLocation = 0;
  attributes[1].format = WGPUVertexFormat_Unorm8x4;
  attributes[1].offset = 12;
  attributes[1].shaderLocation = 1;
  WGPUVertexBufferLayout vb = WGPU_VERTEX_BUFFER_LAYOUT_INIT;
  vb.stepMode = WGPUVertexStepMode_Instance;
  vb.arrayStride = sizeof(PointChunk::Vertex);
  vb.attributeCount = 2;
  vb.attributes = attributes;

  WGPUColorTargetState color_target = WGPU_COLOR_TARGET_STATE_INIT;
  color_target.format = gpu::native(color_format);
  color_target.writeMask = WGPUColorWriteMask_All;
  WGPUFragmentState fragment = WGPU_FRAGMENT_STATE_INIT;
  fragment.module = p.shader.get();
  fragment.entryPoint = gpu::to_view("fs_main");
  fragment.targetCount = 1;
  fragment.targets = &color_target;
  WGPUDepthStencilState depth = WGPU_DEPTH_STENCIL_STATE_INIT;
  depth.format = gpu::native(depth_format);
  depth.depthWriteEnabled = WGPUOptionalBool_True;
  depth.depthCompare = WGPUCompareFunction_Greater;  // reverse Z

  WGPURenderPipelineDescriptor desc = WGPU_RENDER_PIPELINE_DESCRIPTOR_INIT;
  desc.label = gpu::to_view("points");
  desc.layout = p.pipeline_layout.get();
  desc.vertex.module = p.shader.get();
  desc.vertex.entryPoint = gpu::to_view("vs_main");
  desc.vertex.bufferCount = 1;
  desc.vertex.buffers = &vb;
  desc.primitive.topology = WGPUPrimitiveTopology_TriangleStrip;
  desc.primitive.cullMode = WGPUCullMode_None;
  desc.depthStencil = &depth;
  desc.multisample.count = 1;
  desc.multisample.mask = ~0u;
  desc.fragment = &fragment;
  p.pipeline = gpu::RenderPipeline(wgpuDeviceCreateRenderPipeline(ctx.device.get(), &desc));
  p.depth_format = depth_format;
  ctx.check("creating the point pipeline");
  p.timer = gpu::create_pass_timer(ctx, 1);
  p.frame_uniforms =
      gpu::create_buffer(ctx, sizeof(FrameUniforms),
                         WGPUBufferUsage_Uniform | WGPUBufferUsage_CopyDst, "frame-uniforms");
  return p;
}

namespace {
void ensure_chunk_capacity(gpu::Context& ctx, PointPipeline& p, uint32_t chunks) {
  if (chunks <= p.chunk_capacity && p.bind_group) return;
  p.chunk_capacity = std::max<uint32_t>(chunks, 16);
  p.chunk_uniforms =
      gpu::create_buffer(ctx, uint64_t(p.chunk_capacity) * p.chunk_stride,
                         WGPUBufferUsage_Uniform | WGPUBufferUsage_CopyDst, "chunk-uniforms");
  WGPUBindGroupEntry entries[2] = {WGPU_BIND_GROUP_ENTRY_INIT, WGPU_BIND_GROUP_ENTRY_INIT};
  entries[0].binding = 0;
  entries[0].buffer = p.frame_uniforms.get();
  entries[0].size = sizeof(FrameUniforms);
  entries[1].binding = 1;
  entries[1].buffer = p.chunk_uniforms.get();
  entries[1].size = 16;
  WGPUBindGroupDescriptor desc = WGPU_BIND_GROUP_DESCRIPTOR_INIT;
  desc.layout = p.layout.get();
  desc.entryCount = 2;
  desc.entries = entries;
  p.bind_group = gpu::BindGroup(wgpuDeviceCreateBindGroup(ctx.device.get(), &desc));
}
}  // namespace

void add_point_pass(gpu::RenderGraph& graph, PointPipeline& p, const GpuPointCloud& cloud,
                    const Camera& camera, const PointStyle& style, uint32_t width, uint32_t height,
                    const PointPassTargets& targets) {
  auto execute = [&p, &cloud, camera, style, width, height, targets](gpu::PassContext& pc) {
    gpu::Context& ctx = pc.gpu();
    ensure_chunk_capacity(ctx, p, uint32_t(cloud.chunks.size()));

    FrameUniforms frame{};
    // Rotation-only view: the camera is at the origin of what the GPU sees.
    glm::mat4 view_proj =
        glm::mat4(camera.projection(double(width) / height) * camera.view_rotation());
    std::memcpy(frame.view_proj, glm::value_ptr(view_proj), sizeof(frame.view_proj));
    frame.viewport[0] = float(width);
    frame.viewport[1] = float(height);
    frame.point_size = style.point_size;
    frame.round_points = style.round && style.point_size >= 3.0f ? 1u : 0u;
    // Queue writes land before the graph's command buffer, which is submitted after this.
    wgpuQueueWriteBuffer(ctx.queue.get(), p.frame_uniforms.get(), 0, &frame, sizeof(frame));

    // Camera-relative offsets: subtract in double, then cast (seed 000, eq. 5).
    std::vector<uint8_t> offsets(size_t(p.chunk_stride) * std::max<size_t>(1, cloud.chunks.size()));
    for (size_t i = 0; i < cloud.chunks.size(); ++i) {
      glm::dvec3 rel = cloud.chunks[i].origin - camera.position;
      float v[4] = {float(rel.x), float(rel.y), float(rel.z), 0.0f};
      std::memcpy(offsets.data() + i * p.chunk_stride, v, sizeof(v));
    }
    if (!cloud.chunks.empty())
      wgpuQueueWriteBuffer(ctx.queue.get(), p.chunk_uniforms.get(), 0, offsets.data(),
                           offsets.size());

    WGPURenderPassColorAttachment color_attachment = WGPU_RENDER_PASS_COLOR_ATTACHMENT_INIT;
    color_attachment.view = pc.view(targets.color);
    color_attachment.loadOp = WGPULoadOp_Clear;
    color_attachment.storeOp = WGPUStoreOp_Store;
    color_attachment.clearValue = {style.background.r, style.background.g, style.background.b, 1.0};
    WGPURenderPassDepthStencilAttachment depth_attachment =
        WGPU_RENDER_PASS_DEPTH_STENCIL_ATTACHMENT_INIT;
    depth_attachment.view = pc.view(targets.depth);
    depth_attachment.depthLoadOp = WGPULoadOp_Clear;
    // A transient depth buffer is dropped after the pass; an imported one is kept.
    depth_attachment.depthStoreOp = targets.create_depth ? WGPUStoreOp_Discard : WGPUStoreOp_Store;
    depth_attachment.depthClearValue = 0.0f;  // reverse Z: far is 0
    WGPURenderPassDescriptor pass_desc = WGPU_RENDER_PASS_DESCRIPTOR_INIT;
    pass_desc.label = gpu::to_view("points");
    pass_desc.colorAttachmentCount = 1;
    pass_desc.colorAttachments = &color_attachment;
    pass_desc.depthStencilAttachment = &depth_attachment;
    gpu::RenderPassEncoder pass = pc.begin_render_pass(pass_desc);
    wgpuRenderPassEncoderSetPipeline(pass.get(), p.pipeline.get());
    for (size_t i = 0; i < cloud.chunks.size(); ++i) {
      const auto& chunk = cloud.chunks[i];
      uint32_t dynamic_offset = uint32_t(i) * p.chunk_stride;
      wgpuRenderPassEncoderSetBindGroup(pass.get(), 0, p.bind_group.get(), 1, &dynamic_offset);
      wgpuRenderPassEncoderSetVertexBuffer(pass.get(), 0, chunk.vertices.get(), 0,
                                           uint64_t(chunk.count) * sizeof(PointChunk::Vertex));
      wgpuRenderPassEncoderDraw(pass.get(), 4, chunk.count, 0, 0);
    }
    wgpuRenderPassEncoderEnd(pass.get());
  };
  auto pass = graph.add_pass("points", gpu::PassKind::Render, std::move(execute));
  pass.write(targets.color);
  if (targets.create_depth)
    pass.create_texture(targets.depth,
                        {width, height, p.depth_format, WGPUTextureUsage_RenderAttachment});
  else
    pass.write(targets.depth);
}

void draw_points(gpu::Context& ctx, PointPipeline& p, const GpuPointCloud& cloud,
                 const Camera& camera, const PointStyle& style, WGPUTextureView color,
                 WGPUTextureView depth, uint32_t width, uint32_t height) {
  gpu::RenderGraph graph;
  // Only the views are known here; the descriptions are informational for imports.
  graph.import_texture("color", nullptr, color, {width, height, WGPUTextureFormat_Undefined, 0},
                       gpu::Access::Writable);
  graph.import_texture("depth", nullptr, depth, {width, height, p.depth_format, 0},
                       gpu::Access::Writable);
  PointPassTargets targets;
  targets.create_depth = false;
  add_point_pass(graph, p, cloud, camera, style, width, height, targets);
  gpu::TransientPool pool;  // nothing transient
  graph.execute(ctx, pool, &p.timer);
  ctx.check("drawing points");
}

float auto_point_size(const PointCloud& cloud, const Camera& camera, uint32_t height) {
  if (cloud.point_count == 0 || cloud.world_bounds.empty()) return 2.0f;
  glm::dvec3 size = cloud.world_bounds.size();
  // Airborne data covers the horizontal plane (x, -z in world space).
  double area = std::max(size.x * size.z, 1e-9);
  double spacing = std::sqrt(area / double(cloud.point_count));
  double distance = std::max(glm::length(cloud.world_bounds.center() - camera.position), 1e-6);
  double focal = height / (2.0 * std::tan(camera.fov_y * 0.5));
  double pixels = spacing * focal / distance;
  return float(std::clamp(pixels * 1.6, 1.0, 12.0));
}

}  // namespace stipple::pc
