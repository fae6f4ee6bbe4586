#include "stipple/viewer/window_plugins.hpp"

#include <string>

#include "stipple/core/error.hpp"
#include "stipple/engine/engine.hpp"
#include "stipple/engine/render_plugins.hpp"
#include "stipple/engine/viewport.hpp"
#include "stipple/renderer/surface.hpp"

namespace stipple::viewer {
namespace {

void poll_window(Registry& main) {
  auto& w = main.resource<WindowState>();
  // A minimised window draws nothing: sleep in the event wait instead of spinning.
  w.events = platform::poll_events(*w.window, w.minimised ? 0.05 : 0.0);
  w.framebuffer_size = platform::framebuffer_size(*w.window);
  w.window_size = platform::window_size(*w.window);
  w.minimised = platform::minimised(*w.window);
  if (!w.minimised) main.insert_resource(Viewport{w.framebuffer_size.x, w.framebuffer_size.y});
  for (const auto& e : w.events)
    if (e.type == platform::InputEvent::Type::Close) main.resource<AppExit>().requested = true;
}

void update_input(Registry& main) {
  platform::apply_events(main.resource<platform::InputState>(),
                         main.resource<WindowState>().events);
}

// Render-world resource.
struct SurfaceTarget {
  gpu::Surface surface;
  gpu::SurfaceFrame frame;
  glm::uvec2 wanted_size{0};
  bool wanted_vsync = true;
};

const char* present_mode_name(WGPUPresentMode mode) {
  switch (mode) {
    case WGPUPresentMode_Fifo:
      return "fifo (vsync)";
    case WGPUPresentMode_FifoRelaxed:
      return "fifo-relaxed";
    case WGPUPresentMode_Immediate:
      return "immediate";
    case WGPUPresentMode_Mailbox:
      return "mailbox";
    default:
      return "unknown";
  }
}

void extract_surface(Registry& main) {
  Registry& render = *main.resource<RenderWorldRef>();
  auto& target = render.resource<SurfaceTarget>();
  const auto& window = main.resource<WindowState>();
  target.wanted_size = window.minimised ? glm::uvec2(0) : window.framebuffer_size;
  target.wanted_vsync = main.resource<SurfaceSettings>().vsync;
  auto& info = main.resource<SurfaceInfo>();
  info.present_mode = present_mode_name(target.surface.present_mode);
  info.size = {target.surface.width, target.surface.height};
}

void acquire_surface(Registry& render) {
  auto& t = render.resource<SurfaceTarget>();
  gpu::Context& ctx = *render.resource<GpuContext>();
  gpu::Surface& s = t.surface;
  if (!s.configured || s.width != t.wanted_size.x || s.height != t.wanted_size.y ||
      s.vsync != t.wanted_vsync)
    gpu::configure_surface(ctx, s, t.wanted_size.x, t.wanted_size.y, t.wanted_vsync);
  t.frame = gpu::acquire_surface_frame(ctx, s);
  RenderTarget target;
  if (t.frame.ok) {
    target.texture = t.frame.texture.get();
    target.view = t.frame.view.get();
    target.width = s.width;
    target.height = s.height;
    target.format = s.format;
    target.usage = s.usage;
  }
  render.insert_resource(target);
}

void present(Registry& render) {
  auto& t = render.resource<SurfaceTarget>();
  if (!t.frame.ok) return;
  gpu::present_surface(t.surface);
  t.frame = {};
}

}  // namespace

void WindowPlugin::build(Engine& engine) {
  WindowState state;
  state.window = platform::make_window(options);
  state.framebuffer_size = platform::framebuffer_size(*state.window);
  state.window_size = platform::window_size(*state.window);
  engine.main().insert_resource(Viewport{state.framebuffer_size.x, state.framebuffer_size.y});
  engine.main().insert_resource(std::move(state));
  engine.add_system(MainStage::Input, poll_window, "poll_window");
}

void InputPlugin::build(Engine& engine) {
  engine.main().insert_resource(platform::InputState{});
  engine.add_system(MainStage::Input, update_input, "update_input");
}

void SurfaceTargetPlugin::build(Engine& engine) {
  engine.main().insert_resource(SurfaceSettings{vsync});
  engine.main().insert_resource(SurfaceInfo{});
  engine.add_system(MainStage::Extract, extract_surface, "extract_surface");
  engine.add_system(RenderStage::Prepare, acquire_surface, "acquire_surface");
  engine.add_system(RenderStage::PostDraw, present, "present");
}

void SurfaceTargetPlugin::finish(Engine& engine) {
  // After every build(): the window and the device exist whatever the plugin order.
  auto& window = engine.main().resource<WindowState>();
  gpu::Context& ctx = *engine.main().resource<GpuContext>();
  platform::NativeWindow native = platform::native_window(*window.window);
  SurfaceTarget target;
  target.surface = gpu::create_x11_surface(ctx, native.x11_display, native.x11_window);
  target.wanted_size = window.framebuffer_size;
  target.wanted_vsync = vsync;
  engine.render().insert_resource(std::move(target));
}

}  // namespace stipple::viewer
