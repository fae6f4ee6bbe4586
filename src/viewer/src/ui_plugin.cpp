#include "stipple/viewer/ui_plugin.hpp"

#include <memory>
#include <utility>

#include <backends/imgui_impl_glfw.h>
#include <imgui.h>

#include "imgui_webgpu.hpp"
#include "stipple/engine/engine.hpp"
#include "stipple/engine/render_plugins.hpp"
#include "stipple/platform/input.hpp"
#include "stipple/viewer/camera_controller.hpp"
#include "stipple/viewer/script.hpp"
#include "stipple/viewer/window_plugins.hpp"

namespace stipple::viewer {
namespace {

// Main-world resource: owns the ImGui context and its GLFW backend. It keeps the window alive
// so the backend can give the window's callbacks back when it shuts down.
struct UiContext {
  std::shared_ptr<void> owner;
  UiDrawList frame;  // the last ImGui::Render(), until Extract takes it
};

// Render-world resource.
struct UiRenderState {
  UiFontAtlas atlas;
  std::unique_ptr<UiRenderer> renderer;
  UiDrawList draw;  // owned here while the graph runs
  bool visible = true;
};

void ui_begin_frame(Registry& main) {
  ImGui_ImplGlfw_NewFrame();
  if (main.try_resource<ScriptedInputActive>()) {
    // Scripted input: the cursor and buttons of InputState, not the system pointer's. A press
    // and release in one frame still counts as down for that frame.
    const auto& input = main.resource<platform::InputState>();
    ImGuiIO& io = ImGui::GetIO();
    io.MousePos = ImVec2(float(input.cursor.x), float(input.cursor.y));
    for (size_t b = 0; b < platform::kMouseButtonCount; ++b)
      io.MouseDown[b] = input.button_down[b] || input.button_pressed[b];
    io.MouseWheel = float(input.scroll.y);
    io.MouseWheelH = float(input.scroll.x);
  }
  ImGui::NewFrame();
  const ImGuiIO& io = ImGui::GetIO();
  bool visible = main.resource<UiSettings>().visible;
  main.insert_resource(
      UiCapture{visible && io.WantCaptureMouse, visible && io.WantCaptureKeyboard});
}

void ui_end_frame(Registry& main) {
  ImGui::Render();
  UiDrawList draw = copy_draw_data(*ImGui::GetDrawData());
  draw.images = main.resource<UiImages>().images;
  main.resource<UiContext>().frame = std::move(draw);
}

void extract_ui(Registry& main) {
  auto& render = main.resource<RenderWorldRef>()->resource<UiRenderState>();
  render.draw = std::exchange(main.resource<UiContext>().frame, {});
  render.visible = main.resource<UiSettings>().visible;
}

void queue_ui(Registry& render) {
  auto& fg = render.resource<FrameGraph>();
  auto& ui = render.resource<UiRenderState>();
  if (!fg.active || !ui.visible || ui.draw.empty()) return;
  const auto& target = render.resource<RenderTarget>();
  if (!ui.renderer || ui.renderer->format != target.format)
    ui.renderer = create_ui_renderer(*render.resource<GpuContext>(), target.format, ui.atlas);
  add_ui_pass(fg.graph, *ui.renderer, ui.draw, target.width, target.height);
}

}  // namespace

void UiPlugin::build(Engine& engine) {
  Registry& main = engine.main();
  auto window = main.resource<WindowState>().window;
  IMGUI_CHECKVERSION();
  ImGuiContext* context = ImGui::CreateContext();
  ImGuiIO& io = ImGui::GetIO();
  io.IniFilename = nullptr;  // no imgui.ini beside the user's files
  ImGui::StyleColorsDark();
  // Chains to the callbacks the window installed, so our InputState still sees every event.
  ImGui_ImplGlfw_InitForOther(platform::glfw_window(*window), true);
  UiRenderState render_state;
  render_state.atlas = build_font_atlas();
  render_state.visible = visible;
  io.Fonts->SetTexID(ImTextureID(1));  // one texture: the atlas
  UiContext ui;
  ui.owner = std::shared_ptr<void>(context, [window](void* c) {
    ImGui::SetCurrentContext(static_cast<ImGuiContext*>(c));
    ImGui_ImplGlfw_Shutdown();
    ImGui::DestroyContext(static_cast<ImGuiContext*>(c));
  });
  main.insert_resource(std::move(ui));
  main.insert_resource(UiSettings{visible});
  main.insert_resource(UiCapture{});
  main.insert_resource(UiImages{});
  engine.render().insert_resource(std::move(render_state));
  engine.add_system(MainStage::Input, ui_begin_frame, "ui_begin_frame");
  engine.add_system(MainStage::PostUpdate, ui_end_frame, "ui_end_frame");
  engine.add_system(MainStage::Extract, extract_ui, "extract_ui");
  engine.add_system(RenderStage::PreDraw, queue_ui, "queue_ui");
}

}  // namespace stipple::viewer
