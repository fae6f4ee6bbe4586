#pragma once
// Loads one WebGPU implementation (wgpu-native or Dawn) at run time and binds the standard
// webgpu.h entry points to it. Nothing above the renderer module includes this header.
#include <string>
#include <string_view>

#include <webgpu/webgpu.h>
#include <webgpu/wgpu.h>

namespace stipple::gpu {

enum class Backend { Wgpu, Dawn };

std::string_view backend_name(Backend backend);
// "wgpu" / "wgpu-native" / "dawn"; throws stipple::Error on anything else.
Backend parse_backend(std::string_view name);
// The backend chosen by STIPPLE_BACKEND, or the default one.
Backend default_backend();

// Loads the implementation's shared library (once per process: both libraries export the same
// symbol names, so a process binds to one). Throws stipple::Error when it cannot be loaded or
// another backend is already bound.
void load_backend(Backend backend);
// Whether the loaded implementation exports this entry point (e.g. "wgpuDevicePoll").
bool has_proc(const char* name);

// Enum values that differ between webgpu.h revisions. Our code speaks the webgpu.h we compile
// against (the wgpu wheel's); Dawn from bun-webgpu 0.1.7 was built from an older revision that
// numbers texture formats and features differently. These translate at the boundary; they are
// the identity for wgpu-native.
WGPUTextureFormat native_format(WGPUTextureFormat format);
WGPUTextureFormat standard_format(WGPUTextureFormat native);
WGPUFeatureName native_feature(WGPUFeatureName feature);
WGPUFeatureName standard_feature(WGPUFeatureName native);

namespace detail {
size_t bind_procs(void* (*lookup)(void*, const char*), void* library);
bool has_proc(const char* name);
[[noreturn]] void missing_proc(const char* name);
}  // namespace detail

}  // namespace stipple::gpu
