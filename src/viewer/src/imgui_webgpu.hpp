#pragma once
// Dear ImGui on our WebGPU layer: the draw data copied out of ImGui (so the render thread can
// draw frame N while the main thread builds the UI of frame N+1) and a renderer that adds it to
// the frame graph as pass "ui" (font atlas texture, growing vertex/index buffers, scissor rects,
// shaders/imgui.wgsl). Debian's imgui_impl_wgpu speaks an older webgpu.h, hence our own.
#include <cstdint>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include <imgui.h>
#include <glm/vec2.hpp>
#include <glm/vec4.hpp>

#include "stipple/renderer/gpu.hpp"
#include "stipple/renderer/render_graph.hpp"
#include "stipple/viewer/ui_plugin.hpp"

namespace stipple::viewer {

// One frame of UI geometry: every draw list concatenated.
struct UiDrawList {
  struct Command {
    glm::vec4 clip{0.0f};  // x0, y0, x1, y1 in ImGui coordinates
    uint32_t first_index = 0, index_count = 0;
    int32_t base_vertex = 0;
    uintptr_t texture = 1;  // 1: the font atlas; others: `images`
  };
  std::vector<ImDrawVert> vertices;
  std::vector<ImDrawIdx> indices;
  std::vector<Command> commands;
  // The images ImGui::Image drew this frame (immutable, shared with the main world).
  std::map<uintptr_t, std::shared_ptr<const UiImage>> images;
  glm::vec2 display_pos{0.0f}, display_size{0.0f}, framebuffer_scale{1.0f};
  bool empty() const { return commands.empty(); }
};
UiDrawList copy_draw_data(const ImDrawData& data);

struct UiFontAtlas {
  std::vector<uint8_t> rgba;
  uint32_t width = 0, height = 0;
};
// Builds the current ImGui context's font atlas as RGBA8.
UiFontAtlas build_font_atlas();

struct UiRenderer {
  WGPUTextureFormat format = WGPUTextureFormat_Undefined;  // of the target
  gpu::ShaderModule shader;
  gpu::BindGroupLayout layout;
  gpu::PipelineLayout pipeline_layout;
  gpu::RenderPipeline pipeline;
  gpu::Texture font;
  gpu::TextureView font_view;
  gpu::Sampler sampler;
  gpu::Buffer uniforms;
  gpu::BindGroup bind_group;
  gpu::Buffer vertices, indices;
  uint64_t vertex_capacity = 0, index_capacity = 0;  // bytes
  struct Image {
    std::shared_ptr<const UiImage> source;  // what was uploaded
    gpu::Texture texture;
    gpu::TextureView view;
    gpu::BindGroup bind_group;
  };
  std::map<uintptr_t, Image> images;
};
std::unique_ptr<UiRenderer> create_ui_renderer(gpu::Context& ctx, WGPUTextureFormat format,
                                               const UiFontAtlas& atlas);

// Draws the UI over `color` (loaded, not cleared). The draw list must outlive the graph's
// execution.
void add_ui_pass(gpu::RenderGraph& graph, UiRenderer& renderer, const UiDrawList& draw,
                 uint32_t width, uint32_t height, const std::string& color = "color");

}  // namespace stipple::viewer
