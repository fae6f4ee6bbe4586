#include "stipple/renderer/surface.hpp"

#include <algorithm>
#include <initializer_list>

#include "stipple/core/error.hpp"
#include "stipple/core/log.hpp"
#include "webgpu_loader.hpp"
#ifdef __EMSCRIPTEN__
#include "webgpu_web.hpp"
#endif

namespace stipple::gpu {

namespace {

// The surface's format, usage and present modes from its capabilities: the first of `preferred`
// it offers (else its first format); CopySrc where offered, so frames can be read back for
// screenshots. `what` names the surface in errors.
void take_capabilities(Context& ctx, Surface& s, std::initializer_list<WGPUTextureFormat> preferred,
                       const char* what) {
  WGPUSurfaceCapabilities caps = WGPU_SURFACE_CAPABILITIES_INIT;
  if (wgpuSurfaceGetCapabilities(s.surface.get(), ctx.adapter.get(), &caps) != WGPUStatus_Success)
    fail("{}: the adapter cannot present to {}", ctx.description.backend, what);
  std::vector<WGPUTextureFormat> formats;
  for (size_t i = 0; i < caps.formatCount; ++i) formats.push_back(standard_format(caps.formats[i]));
  for (size_t i = 0; i < caps.presentModeCount; ++i)
    s.present_modes.push_back(caps.presentModes[i]);
  WGPUTextureUsage usages = caps.usages;
  wgpuSurfaceCapabilitiesFreeMembers(caps);
  if (formats.empty()) fail("{}: {} offers no texture format", ctx.description.backend, what);
  s.format = formats.front();
  for (WGPUTextureFormat f : preferred)
    if (std::find(formats.begin(), formats.end(), f) != formats.end()) {
      s.format = f;
      break;
    }
  s.usage = WGPUTextureUsage_RenderAttachment;
  if (usages & WGPUTextureUsage_CopySrc) s.usage |= WGPUTextureUsage_CopySrc;
  STIPPLE_DEBUG("surface: format {}, usages 0x{:x}, {} present modes", int(s.format),
                uint64_t(usages), s.present_modes.size());
}

}  // namespace

Surface create_x11_surface(Context& ctx, void* x11_display, uint64_t x11_window) {
  // The same chained struct for wgpu-native and Dawn: both number SurfaceSourceXlibWindow 6.
  WGPUSurfaceSourceXlibWindow source = WGPU_SURFACE_SOURCE_XLIB_WINDOW_INIT;
  source.display = x11_display;
  source.window = x11_window;
  WGPUSurfaceDescriptor desc = WGPU_SURFACE_DESCRIPTOR_INIT;
  desc.nextInChain = &source.chain;
  desc.label = to_view("stipple-window");
  Surface s;
  s.surface = SurfaceHandle(wgpuInstanceCreateSurface(ctx.instance.get(), &desc));
  if (!s.surface)
    fail("{}: could not create a surface for the X11 window", ctx.description.backend);
  take_capabilities(ctx, s, {WGPUTextureFormat_BGRA8Unorm, WGPUTextureFormat_RGBA8Unorm},
                    "this window");
  return s;
}

Surface create_canvas_surface(Context& ctx, const char* selector) {
#ifdef __EMSCRIPTEN__
  web::SurfaceSourceCanvasSelector source{};
  source.chain.sType = web::kSurfaceSourceCanvasSelector;
  source.selector = selector;
  WGPUSurfaceDescriptor desc = WGPU_SURFACE_DESCRIPTOR_INIT;
  desc.nextInChain = &source.chain;
  desc.label = to_view("stipple-canvas");
  Surface s;
  s.surface = SurfaceHandle(wgpuInstanceCreateSurface(ctx.instance.get(), &desc));
  if (!s.surface) fail("no WebGPU canvas context for '{}'", selector);
  // The canvas's preferred format comes first (webgpu_web.cpp): any other costs the browser a
  // conversion when it composites the page.
  take_capabilities(ctx, s, {}, "the canvas");
  // A canvas texture takes storage writes in a format that has them (RGBA8, not BGRA8 without
  // a feature): the compute rasterizer's display pass then writes it directly (a compute pass)
  // instead of through a render pass.
  if (s.format == WGPUTextureFormat_RGBA8Unorm) s.usage |= WGPUTextureUsage_StorageBinding;
  return s;
#else
  (void)ctx;
  fail("a canvas ('{}') exists only in the browser build", selector);
#endif
}

WGPUPresentMode choose_present_mode(const std::vector<WGPUPresentMode>& supported, bool vsync) {
  if (!vsync)
    for (WGPUPresentMode m : {WGPUPresentMode_Immediate, WGPUPresentMode_Mailbox})
      if (std::find(supported.begin(), supported.end(), m) != supported.end()) return m;
  return WGPUPresentMode_Fifo;
}

void configure_surface(Context& ctx, Surface& s, uint32_t width, uint32_t height, bool vsync) {
  if (width == 0 || height == 0) {
    if (s.configured) wgpuSurfaceUnconfigure(s.surface.get());
    s.configured = false;
    s.width = s.height = 0;
    return;
  }
  WGPUSurfaceConfiguration config = WGPU_SURFACE_CONFIGURATION_INIT;
  config.device = ctx.device.get();
  config.format = native(s.format);
  config.usage = s.usage;
  config.width = width;
  config.height = height;
  config.alphaMode = WGPUCompositeAlphaMode_Auto;
  config.presentMode = choose_present_mode(s.present_modes, vsync);
  wgpuSurfaceConfigure(s.surface.get(), &config);
  s.present_mode = config.presentMode;
  s.width = width;
  s.height = height;
  s.vsync = vsync;
  s.configured = true;
}

SurfaceFrame acquire_surface_frame(Context& ctx, Surface& s) {
  SurfaceFrame frame;
  if (!s.configured) return frame;
  // Room for implementations built from older headers with more members.
  struct {
    WGPUSurfaceTexture st = WGPU_SURFACE_TEXTURE_INIT;
    uint64_t trailing[4] = {};
  } storage;
  wgpuSurfaceGetCurrentTexture(s.surface.get(), &storage.st);
  const uint32_t status = uint32_t(storage.st.status);
  // SuccessOptimal (1) and SuccessSuboptimal (2) are numbered alike in both implementations.
  if (storage.st.texture && (status == 1 || status == 2)) {
    frame.texture = Texture(storage.st.texture);
    frame.view = create_view(frame.texture);
    frame.ok = true;
    return frame;
  }
  if (storage.st.texture) wgpuTextureRelease(storage.st.texture);
  STIPPLE_DEBUG("surface texture unavailable (status {}): reconfiguring", status);
  configure_surface(ctx, s, s.width, s.height, s.vsync);
  return frame;
}

void present_surface(Surface& s) {
  wgpuSurfacePresent(s.surface.get());
}

}  // namespace stipple::gpu
