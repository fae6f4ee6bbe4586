#include "canvas_target.hpp"

#include <utility>

#include "stipple/engine/engine.hpp"
#include "stipple/engine/render_plugins.hpp"
#include "stipple/engine/viewport.hpp"
#include "stipple/renderer/surface.hpp"

namespace stipple::web {
namespace {

// Render-world resource: the canvas's surface, the size the page wants and this frame's texture.
struct CanvasTarget {
  gpu::Surface surface;
  gpu::SurfaceFrame frame;
  uint32_t wanted_width = 0, wanted_height = 0;
};

void extract_canvas(Registry& main) {
  auto& target = main.resource<RenderWorldRef>()->resource<CanvasTarget>();
  const auto& viewport = main.resource<Viewport>();
  target.wanted_width = viewport.width;
  target.wanted_height = viewport.height;
}

// Configures the surface for the wanted size (the browser resizes the canvas's drawing buffer
// with it) and describes the target; its texture is taken later (take_canvas_texture).
void prepare_canvas(Registry& render) {
  auto& t = render.resource<CanvasTarget>();
  gpu::Surface& s = t.surface;
  if (!s.configured || s.width != t.wanted_width || s.height != t.wanted_height)
    gpu::configure_surface(*render.resource<GpuContext>(), s, t.wanted_width, t.wanted_height,
                           true);
  // As configured for this frame (the stats read it once the frame is drawn).
  render.insert_resource(CanvasInfo{s.format, s.width, s.height});
  RenderTarget target;
  if (s.configured) {
    target.width = s.width;
    target.height = s.height;
    target.format = s.format;
    target.usage = s.usage;
    target.acquire = [&render](RenderTarget& late) {
      auto& c = render.resource<CanvasTarget>();
      c.frame = gpu::acquire_surface_frame(*render.resource<GpuContext>(), c.surface);
      if (!c.frame.ok) return false;
      late.texture = c.frame.texture.get();
      late.view = c.frame.view.get();
      return true;
    };
  }
  render.insert_resource(std::move(target));
}

void present_canvas(Registry& render) {
  auto& t = render.resource<CanvasTarget>();
  if (!t.frame.ok) return;
  gpu::present_surface(t.surface);  // the browser presents once the thread yields
  auto& target = render.resource<RenderTarget>();
  target.texture = nullptr;
  target.view = nullptr;
  t.frame = {};
}

}  // namespace

const char* canvas_format_name(WGPUTextureFormat format) {
  switch (format) {
    case WGPUTextureFormat_BGRA8Unorm:
      return "bgra8unorm";
    case WGPUTextureFormat_RGBA8Unorm:
      return "rgba8unorm";
    case WGPUTextureFormat_RGBA16Float:
      return "rgba16float";
    default:
      return "other";
  }
}

void CanvasTargetPlugin::build(Engine& engine) {
  engine.main().insert_resource(Viewport{width, height});
  engine.render().insert_resource(CanvasInfo{});
  engine.add_system(MainStage::Extract, extract_canvas, "extract_canvas");
  engine.add_system(RenderStage::Prepare, prepare_canvas, "prepare_canvas");
  engine.add_system(RenderStage::PostDraw, present_canvas, "present_canvas");
}

void CanvasTargetPlugin::finish(Engine& engine) {
  // After every build(): the device exists whatever the plugin order.
  CanvasTarget target;
  target.surface =
      gpu::create_canvas_surface(*engine.main().resource<GpuContext>(), selector.c_str());
  target.wanted_width = width;
  target.wanted_height = height;
  engine.render().insert_resource(std::move(target));
}

}  // namespace stipple::web
