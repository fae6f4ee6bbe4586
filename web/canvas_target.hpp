#pragma once
// The page's canvas as the engine's render target: every frame is drawn straight into the
// canvas's WebGPU context (no readback, no copy), and the browser shows it once the page's thread
// yields. The canvas's drawing buffer follows the main world's Viewport, which the page's program
// sets when the canvas's container or devicePixelRatio changes: the surface is reconfigured
// before the next frame (the browser resizes the canvas with it). The frame's texture is taken
// in Draw, right before the graph runs (RenderTarget::acquire): one taken in Prepare could expire
// while a Prepare or Queue system yields to the page (a shader compiled, a buffer mapped).
//
// Only the page has a canvas, so the plugin is the page's own; the surface over a canvas is the
// renderer's (gpu::create_canvas_surface, beside the window's), and late acquisition the engine's
// (any target whose texture expires when the thread yields).
#include <array>
#include <cstdint>
#include <string>
#include <string_view>

#include "stipple/renderer/gpu.hpp"

namespace stipple {
class Engine;
}

namespace stipple::web {

struct CanvasTargetPlugin {
  static constexpr std::string_view name = "CanvasTargetPlugin";
  static constexpr std::string_view description =
      "the page's WebGPU canvas as RenderTarget, its size following Viewport";
  static constexpr std::array<std::string_view, 2> dependencies{"GpuPlugin", "RenderGraphPlugin"};
  std::string selector = "#canvas";
  uint32_t width = 1280, height = 720;  // the drawing buffer's first size (Viewport)
  void build(Engine& engine);
  void finish(Engine& engine);
};

// Render-world resource: the canvas as configured for the last frame (the page's stats; the page
// renders on its main thread, so the stats read it between frames).
struct CanvasInfo {
  WGPUTextureFormat format = WGPUTextureFormat_Undefined;
  uint32_t width = 0, height = 0;
};

// The name of a canvas format for the page ("bgra8unorm", "rgba8unorm").
const char* canvas_format_name(WGPUTextureFormat format);

}  // namespace stipple::web
