#pragma once
// Presenting to a window: a WebGPU surface made from native (X11) handles, configured for the
// window's size with FIFO (vsync) or Immediate/Mailbox (no vsync) where the surface offers them;
// in the browser build, a surface over an HTML canvas (the page's WebGPU canvas context), which
// the browser presents when the page's thread yields. The renderer does not know about GLFW or
// the page: the platform module hands over the handles, the page names its canvas.
#include <cstdint>
#include <vector>

#include "stipple/renderer/gpu.hpp"

namespace stipple::gpu {

using SurfaceHandle = Handle<WGPUSurface, wgpuSurfaceRelease>;

struct Surface {
  SurfaceHandle surface;
  WGPUTextureFormat format = WGPUTextureFormat_Undefined;  // standard numbering
  WGPUTextureUsage usage = WGPUTextureUsage_RenderAttachment;
  WGPUPresentMode present_mode = WGPUPresentMode_Fifo;
  std::vector<WGPUPresentMode> present_modes;  // what the surface supports
  uint32_t width = 0, height = 0;              // configured size; 0 while unconfigured
  bool vsync = true;
  bool configured = false;
};

// Creates the surface for an X11 window (Display*, Window). Throws stipple::Error.
Surface create_x11_surface(Context& ctx, void* x11_display, uint64_t x11_window);

// Creates the surface for the page's canvas named by a CSS selector ("#canvas"), in its
// preferred format (a compositor copy saved). Browser build only; elsewhere, and where the
// selector names no canvas, throws stipple::Error.
Surface create_canvas_surface(Context& ctx, const char* selector);

// The present mode for a vsync setting among the supported ones: FIFO with vsync (always
// supported); otherwise Immediate, then Mailbox, then FIFO.
WGPUPresentMode choose_present_mode(const std::vector<WGPUPresentMode>& supported, bool vsync);

// (Re)configures for a size and vsync setting; a 0x0 size (minimised) unconfigures. The format
// prefers BGRA8Unorm/RGBA8Unorm (not sRGB: our shaders write display values); CopySrc is added
// when offered, so frames can be read back for screenshots.
void configure_surface(Context& ctx, Surface& surface, uint32_t width, uint32_t height, bool vsync);

struct SurfaceFrame {
  Texture texture;
  TextureView view;
  bool ok = false;  // false: skip this frame (outdated, lost, timeout); reconfigure first
};
// The next texture to draw into. On an outdated or lost surface it reconfigures with the same
// size and returns !ok; the caller tries again next frame.
SurfaceFrame acquire_surface_frame(Context& ctx, Surface& surface);
void present_surface(Surface& surface);

}  // namespace stipple::gpu
