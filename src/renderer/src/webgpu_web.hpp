#pragma once
// The browser's WebGPU (web build only): the standard webgpu.h entry points that the rest of
// stipple calls, implemented over emscripten 3.1.69's older webgpu.h (webgpu_web.cpp).
#include <webgpu/webgpu.h>

namespace stipple::gpu::web {

// The entry point of this name, or null where the browser has none (wgpuDevicePoll, ...).
void* lookup(const char* name);

// A surface over an HTML canvas: chain this to a WGPUSurfaceDescriptor. Its sType lies in a
// range no webgpu.h revision uses.
constexpr WGPUSType kSurfaceSourceCanvasSelector = WGPUSType(0x7E000001);
struct SurfaceSourceCanvasSelector {
  WGPUChainedStruct chain;
  const char* selector;  // "#canvas"
};

}  // namespace stipple::gpu::web
