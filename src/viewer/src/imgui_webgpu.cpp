#include "imgui_webgpu.hpp"

#include <algorithm>
#include <cstddef>
#include <cstring>

#include "stipple/core/error.hpp"
#include "stipple/renderer/shader_preprocessor.hpp"

namespace stipple::viewer {

UiDrawList copy_draw_data(const ImDrawData& data) {
  UiDrawList out;
  out.display_pos = {data.DisplayPos.x, data.DisplayPos.y};
  out.display_size = {data.DisplaySize.x, data.DisplaySize.y};
  out.framebuffer_scale = {data.FramebufferScale.x, data.FramebufferScale.y};
  out.vertices.reserve(size_t(data.TotalVtxCount));
  out.indices.reserve(size_t(data.TotalIdxCount));
  for (int l = 0; l < data.CmdListsCount; ++l) {
    const ImDrawList& list = *data.CmdLists[l];
    const uint32_t vertex_base = uint32_t(out.vertices.size());
    const uint32_t index_base = uint32_t(out.indices.size());
    out.vertices.insert(out.vertices.end(), list.VtxBuffer.begin(), list.VtxBuffer.end());
    out.indices.insert(out.indices.end(), list.IdxBuffer.begin(), list.IdxBuffer.end());
    for (const ImDrawCmd& cmd : list.CmdBuffer) {
      if (cmd.UserCallback) continue;  // we install none
      UiDrawList::Command c;
      c.clip = {cmd.ClipRect.x, cmd.ClipRect.y, cmd.ClipRect.z, cmd.ClipRect.w};
      c.first_index = index_base + cmd.IdxOffset;
      c.index_count = cmd.ElemCount;
      c.base_vertex = int32_t(vertex_base + cmd.VtxOffset);
      c.texture = reinterpret_cast<uintptr_t>(cmd.TextureId);
      out.commands.push_back(c);
    }
  }
  return out;
}

UiFontAtlas build_font_atlas() {
  unsigned char* pixels = nullptr;
  int width = 0, height = 0;
  ImGui::GetIO().Fonts->GetTexDataAsRGBA32(&pixels, &width, &height);
  UiFontAtlas atlas;
  atlas.width = uint32_t(width);
  atlas.height = uint32_t(height);
  atlas.rgba.assign(pixels, pixels + size_t(width) * height * 4);
  return atlas;
}

namespace {
struct Uniforms {
  float scale[2];
  float translate[2];
};

void ensure_buffer(gpu::Context& ctx, gpu::Buffer& buffer, uint64_t& capacity, uint64_t size,
                   WGPUBufferUsage usage, const char* label) {
  if (size <= capacity && buffer) return;
  capacity = std::max<uint64_t>(size + size / 2, 64 * 1024);
  capacity = (capacity + 3) & ~uint64_t(3);
  buffer = gpu::create_buffer(ctx, capacity, usage | WGPUBufferUsage_CopyDst, label);
}

}  // namespace

std::unique_ptr<UiRenderer> create_ui_renderer(gpu::Context& ctx, WGPUTextureFormat format,
                                               const UiFontAtlas& atlas) {
  static_assert(sizeof(ImDrawIdx) == 2 || sizeof(ImDrawIdx) == 4);
  auto r = std::make_unique<UiRenderer>();
  r->format = format;
  r->shader = gpu::create_shader_from_file(ctx, "imgui.wgsl");

  WGPUBindGroupLayoutEntry entries[3] = {WGPU_BIND_GROUP_LAYOUT_ENTRY_INIT,
                                         WGPU_BIND_GROUP_LAYOUT_ENTRY_INIT,
                                         WGPU_BIND_GROUP_LAYOUT_ENTRY_INIT};
  entries[0].binding = 0;
  entries[0].visibility = WGPUShaderStage_Vertex;
  entries[0].buffer.type = WGPUBufferBindingType_Uniform;
  entries[0].buffer.minBindingSize = sizeof(Uniforms);
  entries[1].binding = 1;
  entries[1].visibility = WGPUShaderStage_Fragment;
  entries[1].sampler.type = WGPUSamplerBindingType_Filtering;
  entries[2].binding = 2;
  entries[2].visibility = WGPUShaderStage_Fragment;
  entries[2].texture.sampleType = WGPUTextureSampleType_Float;
  entries[2].texture.viewDimension = WGPUTextureViewDimension_2D;
  WGPUBindGroupLayoutDescriptor layout_desc = WGPU_BIND_GROUP_LAYOUT_DESCRIPTOR_INIT;
  layout_desc.entryCount = 3;
  layout_desc.entries = entries;
  r->layout = gpu::BindGroupLayout(wgpuDeviceCreateBindGroupLayout(ctx.device.get(), &layout_desc));
  WGPUBindGroupLayout layouts[] = {r->layout.get()};
  WGPUPipelineLayoutDescriptor pl_desc = WGPU_PIPELINE_LAYOUT_DESCRIPTOR_INIT;
  pl_desc.bindGroupLayoutCount = 1;
  pl_desc.bindGroupLayouts = layouts;
  r->pipeline_layout =
      gpu::PipelineLayout(wgpuDeviceCreatePipelineLayout(ctx.device.get(), &pl_desc));

  WGPUVertexAttribute attributes[3] = {WGPU_VERTEX_ATTRIBUTE_INIT, WGPU_VERTEX_ATTRIBUTE_INIT,
                                       WGPU_VERTEX_ATTRIBUTE_INIT};
  attributes[0].format = WGPUVertexFormat_Float32x2;
  attributes[0].offset = offsetof(ImDrawVert, pos);
  attributes[0].shaderLocation = 0;
  attributes[1].format = WGPUVertexFormat_Float32x2;
  attributes[1].offset = offsetof(ImDrawVert, uv);
  attributes[1].shaderLocation = 1;
  attributes[2].format = WGPUVertexFormat_Unorm8x4;  // ImU32 colour, R in the low byte
  attributes[2].offset = offsetof(ImDrawVert, col);
  attributes[2].shaderLocation = 2;
  WGPUVertexBufferLayout vb = WGPU_VERTEX_BUFFER_LAYOUT_INIT;
  vb.stepMode = WGPUVertexStepMode_Vertex;
  vb.arrayStride = sizeof(ImDrawVert);
  vb.attributeCount = 3;
  vb.attributes = attributes;

  WGPUBlendState blend = WGPU_BLEND_STATE_INIT;
  blend.color = {WGPUBlendOperation_Add, WGPUBlendFactor_SrcAlpha,
                 WGPUBlendFactor_OneMinusSrcAlpha};
  blend.alpha = {WGPUBlendOperation_Add, WGPUBlendFactor_One, WGPUBlendFactor_OneMinusSrcAlpha};
  WGPUColorTargetState color_target = WGPU_COLOR_TARGET_STATE_INIT;
  color_target.format = gpu::native(format);
  color_target.blend = &blend;
  color_target.writeMask = WGPUColorWriteMask_All;
  WGPUFragmentState fragment = WGPU_FRAGMENT_STATE_INIT;
  fragment.module = r->shader.get();
  fragment.entryPoint = gpu::to_view("fs_main");
  fragment.targetCount = 1;
  fragment.targets = &color_target;
  WGPURenderPipelineDescriptor desc = WGPU_RENDER_PIPELINE_DESCRIPTOR_INIT;
  desc.label = gpu::to_view("ui");
  desc.layout = r->pipeline_layout.get();
  desc.vertex.module = r->shader.get();
  desc.vertex.entryPoint = gpu::to_view("vs_main");
  desc.vertex.bufferCount = 1;
  desc.vertex.buffers = &vb;
  desc.primitive.topology = WGPUPrimitiveTopology_TriangleList;
  desc.primitive.cullMode = WGPUCullMode_None;
  desc.multisample.count = 1;
  desc.multisample.mask = ~0u;
  desc.fragment = &fragment;
  r->pipeline = gpu::RenderPipeline(wgpuDeviceCreateRenderPipeline(ctx.device.get(), &desc));

  // The font atlas, uploaded once.
  r->font =
      gpu::create_texture_2d(ctx, atlas.width, atlas.height, WGPUTextureFormat_RGBA8Unorm,
                             WGPUTextureUsage_TextureBinding | WGPUTextureUsage_CopyDst, "ui-font");
  r->font_view = gpu::create_view(r->font);
  WGPUTexelCopyTextureInfo dst = WGPU_TEXEL_COPY_TEXTURE_INFO_INIT;
  dst.texture = r->font.get();
  WGPUTexelCopyBufferLayout src_layout = WGPU_TEXEL_COPY_BUFFER_LAYOUT_INIT;
  src_layout.bytesPerRow = atlas.width * 4;
  src_layout.rowsPerImage = atlas.height;
  WGPUExtent3D extent = {atlas.width, atlas.height, 1};
  wgpuQueueWriteTexture(ctx.queue.get(), &dst, atlas.rgba.data(), atlas.rgba.size(), &src_layout,
                        &extent);
  WGPUSamplerDescriptor sampler_desc = WGPU_SAMPLER_DESCRIPTOR_INIT;
  sampler_desc.magFilter = WGPUFilterMode_Linear;
  sampler_desc.minFilter = WGPUFilterMode_Linear;
  r->sampler = gpu::Sampler(wgpuDeviceCreateSampler(ctx.device.get(), &sampler_desc));
  r->uniforms = gpu::create_buffer(
      ctx, sizeof(Uniforms), WGPUBufferUsage_Uniform | WGPUBufferUsage_CopyDst, "ui-uniforms");
  r->bind_group = gpu::create_bind_group(
      ctx, r->layout.get(),
      {gpu::bind_buffer(0, r->uniforms.get(), 0, sizeof(Uniforms)),
       gpu::bind_sampler(1, r->sampler.get()), gpu::bind_texture(2, r->font_view.get())});
  ctx.check("creating the UI renderer");
  return r;
}

namespace {

// Uploads the images the frame draws that changed since they were last uploaded.
void update_images(gpu::Context& ctx, UiRenderer& r, const UiDrawList& draw) {
  for (const auto& [id, image] : draw.images) {
    UiRenderer::Image& slot = r.images[id];
    if (slot.source == image || !image || image->width == 0 || image->height == 0) continue;
    slot.source = image;
    slot.texture = gpu::create_texture_2d(
        ctx, image->width, image->height, WGPUTextureFormat_RGBA8Unorm,
        WGPUTextureUsage_TextureBinding | WGPUTextureUsage_CopyDst, "ui-image");
    slot.view = gpu::create_view(slot.texture);
    WGPUTexelCopyTextureInfo dst = WGPU_TEXEL_COPY_TEXTURE_INFO_INIT;
    dst.texture = slot.texture.get();
    WGPUTexelCopyBufferLayout layout = WGPU_TEXEL_COPY_BUFFER_LAYOUT_INIT;
    layout.bytesPerRow = image->width * 4;
    layout.rowsPerImage = image->height;
    WGPUExtent3D extent = {image->width, image->height, 1};
    wgpuQueueWriteTexture(ctx.queue.get(), &dst, image->rgba.data(), image->rgba.size(), &layout,
                          &extent);
    slot.bind_group = gpu::create_bind_group(
        ctx, r.layout.get(),
        {gpu::bind_buffer(0, r.uniforms.get(), 0, sizeof(Uniforms)),
         gpu::bind_sampler(1, r.sampler.get()), gpu::bind_texture(2, slot.view.get())});
  }
}

}  // namespace

void add_ui_pass(gpu::RenderGraph& graph, UiRenderer& r, const UiDrawList& draw, uint32_t width,
                 uint32_t height, const std::string& color) {
  auto execute = [&r, &draw, width, height, color](gpu::PassContext& pc) {
    gpu::Context& ctx = pc.gpu();
    update_images(ctx, r, draw);
    const uint64_t vertex_bytes = draw.vertices.size() * sizeof(ImDrawVert);
    const uint64_t index_bytes = draw.indices.size() * sizeof(ImDrawIdx);
    ensure_buffer(ctx, r.vertices, r.vertex_capacity, vertex_bytes, WGPUBufferUsage_Vertex,
                  "ui-vertices");
    ensure_buffer(ctx, r.indices, r.index_capacity, index_bytes + 4, WGPUBufferUsage_Index,
                  "ui-indices");
    gpu::write_buffer(ctx, r.vertices.get(), 0, draw.vertices.data(), vertex_bytes);
    gpu::write_buffer(ctx, r.indices.get(), 0, draw.indices.data(), index_bytes);
    // ImGui coordinates to clip space (y down to y up).
    Uniforms u;
    u.scale[0] = 2.0f / draw.display_size.x;
    u.scale[1] = -2.0f / draw.display_size.y;
    u.translate[0] = -1.0f - draw.display_pos.x * u.scale[0];
    u.translate[1] = 1.0f - draw.display_pos.y * u.scale[1];
    gpu::write_buffer(ctx, r.uniforms.get(), 0, u);

    WGPURenderPassColorAttachment attachment = WGPU_RENDER_PASS_COLOR_ATTACHMENT_INIT;
    attachment.view = pc.view(color);
    attachment.loadOp = WGPULoadOp_Load;
    attachment.storeOp = WGPUStoreOp_Store;
    WGPURenderPassDescriptor desc = WGPU_RENDER_PASS_DESCRIPTOR_INIT;
    desc.label = gpu::to_view("ui");
    desc.colorAttachmentCount = 1;
    desc.colorAttachments = &attachment;
    gpu::RenderPassEncoder pass = pc.begin_render_pass(desc);
    wgpuRenderPassEncoderSetPipeline(pass.get(), r.pipeline.get());
    gpu::set_bind_groups(pass.get(), {r.bind_group.get()});
    uintptr_t bound = 1;
    wgpuRenderPassEncoderSetVertexBuffer(pass.get(), 0, r.vertices.get(), 0, r.vertex_capacity);
    wgpuRenderPassEncoderSetIndexBuffer(
        pass.get(), r.indices.get(),
        sizeof(ImDrawIdx) == 2 ? WGPUIndexFormat_Uint16 : WGPUIndexFormat_Uint32, 0,
        r.index_capacity);
    const glm::vec2 offset = draw.display_pos, scale = draw.framebuffer_scale;
    for (const auto& cmd : draw.commands) {
      // Clip rectangle in framebuffer pixels, inside the target.
      float x0 = std::max((cmd.clip.x - offset.x) * scale.x, 0.0f);
      float y0 = std::max((cmd.clip.y - offset.y) * scale.y, 0.0f);
      float x1 = std::min((cmd.clip.z - offset.x) * scale.x, float(width));
      float y1 = std::min((cmd.clip.w - offset.y) * scale.y, float(height));
      if (x1 <= x0 || y1 <= y0 || cmd.index_count == 0) continue;
      if (cmd.texture != bound) {
        auto it = r.images.find(cmd.texture);
        if (cmd.texture != 1 && (it == r.images.end() || !it->second.bind_group)) continue;
        gpu::set_bind_groups(pass.get(),
                             {cmd.texture == 1 ? r.bind_group.get() : it->second.bind_group.get()});
        bound = cmd.texture;
      }
      wgpuRenderPassEncoderSetScissorRect(pass.get(), uint32_t(x0), uint32_t(y0), uint32_t(x1 - x0),
                                          uint32_t(y1 - y0));
      wgpuRenderPassEncoderDrawIndexed(pass.get(), cmd.index_count, 1, cmd.first_index,
                                       cmd.base_vertex, 0);
    }
    wgpuRenderPassEncoderEnd(pass.get());
  };
  graph.add_pass("ui", gpu::PassKind::Render, std::move(execute)).write(color);
}

}  // namespace stipple::viewer
