#include "webgpu_loader.hpp"

#ifdef __EMSCRIPTEN__
#include "webgpu_web.hpp"
#else
#include <dlfcn.h>
#endif

#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <mutex>
#include <optional>

#include "stipple/core/error.hpp"
#include "stipple/core/log.hpp"

namespace stipple::gpu {
namespace {

std::mutex g_mutex;
std::optional<Backend> g_loaded;

#ifndef __EMSCRIPTEN__
// The library for a backend: an explicit override, the SDK setup.sh unpacked (path compiled in),
// or the plain soname for installed copies.
std::string library_path(Backend backend) {
  const char* env =
      std::getenv(backend == Backend::Wgpu ? "STIPPLE_WGPU_LIBRARY" : "STIPPLE_DAWN_LIBRARY");
  if (env && *env) return env;
  const char* built = backend == Backend::Wgpu ? STIPPLE_WGPU_LIB : STIPPLE_DAWN_LIB;
  if (std::filesystem::exists(built)) return built;
  return backend == Backend::Wgpu ? "libwgpu_native-release.so" : "libwebgpu_wrapper.so";
}

#endif

void* lookup(void* library, const char* name) {
#ifdef __EMSCRIPTEN__
  (void)library;
  return web::lookup(name);
#else
  return dlsym(library, name);
#endif
}

}  // namespace

std::string_view backend_name(Backend backend) {
#ifdef __EMSCRIPTEN__
  (void)backend;
  return "browser";  // the page's WebGPU, whichever the backend option says
#endif
  return backend == Backend::Wgpu ? "wgpu" : "dawn";
}

Backend parse_backend(std::string_view name) {
  if (name == "wgpu" || name == "wgpu-native") return Backend::Wgpu;
  if (name == "dawn") return Backend::Dawn;
  fail("unknown WebGPU backend '{}' (expected 'dawn' or 'wgpu')", name);
}

Backend default_backend() {
  const char* env = std::getenv("STIPPLE_BACKEND");
  if (env && *env) return parse_backend(env);
  return Backend::STIPPLE_DEFAULT_BACKEND;
}

void load_backend(Backend backend) {
  std::lock_guard lock(g_mutex);
  if (g_loaded) {
    if (*g_loaded == backend) return;
    fail("WebGPU backend '{}' is already loaded in this process; cannot switch to '{}'",
         backend_name(*g_loaded), backend_name(backend));
  }
#ifdef __EMSCRIPTEN__
  // The browser's WebGPU, through webgpu_web.cpp.
  size_t bound = detail::bind_procs(lookup, nullptr);
  STIPPLE_DEBUG("bound the browser's WebGPU ({} entry points)", bound);
  g_loaded = backend;
#else
  std::string path = library_path(backend);
  void* library = dlopen(path.c_str(), RTLD_NOW | RTLD_LOCAL);
  if (!library) {
    fail("cannot load the {} WebGPU library {}: {} (run scripts/setup.sh --deps)",
         backend_name(backend), path, dlerror());
  }
  size_t bound = detail::bind_procs(lookup, library);
  if (!detail::has_proc("wgpuCreateInstance")) {
    fail("{} does not export wgpuCreateInstance: not a webgpu.h implementation", path);
  }
  STIPPLE_DEBUG("loaded {} ({} entry points bound)", path, bound);
  g_loaded = backend;
#endif
}

bool has_proc(const char* name) {
  return detail::has_proc(name);
}

namespace {
bool dawn_loaded() {
  return g_loaded && *g_loaded == Backend::Dawn;
}

// Dawn's older numbering: the 16-bit normalised formats were Dawn extensions at 0x00050000..5
// and the rest of the list is shifted down by the six slots they take in the newer header.
constexpr uint32_t kDawnNorm16[6][2] = {
    {WGPUTextureFormat_R16Unorm, 0x00050000},    {WGPUTextureFormat_RG16Unorm, 0x00050001},
    {WGPUTextureFormat_RGBA16Unorm, 0x00050002}, {WGPUTextureFormat_R16Snorm, 0x00050003},
    {WGPUTextureFormat_RG16Snorm, 0x00050004},   {WGPUTextureFormat_RGBA16Snorm, 0x00050005},
};
uint32_t dawn_format_shift(uint32_t standard) {
  if (standard < WGPUTextureFormat_R16Unorm) return 0;
  if (standard < WGPUTextureFormat_RG16Unorm) return 2;
  if (standard < WGPUTextureFormat_RGBA16Unorm) return 4;
  return 6;
}

// Features 0x1..0x16 of the newer header in the order Dawn numbered them (1-based), 0 if Dawn
// has no such standard feature.
constexpr uint32_t kDawnFeature[] = {
    0,   // undefined
    18,  // core-features-and-limits
    1,   // depth-clip-control
    2,   // depth32float-stencil8
    4,   // texture-compression-bc
    5,   // texture-compression-bc-sliced-3d
    6,   // texture-compression-etc2
    7,   // texture-compression-astc
    8,   // texture-compression-astc-sliced-3d
    3,   // timestamp-query
    9,   // indirect-first-instance
    10,  // shader-f16
    11,  // rg11b10ufloat-renderable
    12,  // bgra8unorm-storage
    13,  // float32-filterable
    14,  // float32-blendable
    15,  // clip-distances
    16,  // dual-source-blending
    17,  // subgroups
};
constexpr uint32_t kDawnFeatureCount = sizeof(kDawnFeature) / sizeof(kDawnFeature[0]);
}  // namespace

WGPUTextureFormat native_format(WGPUTextureFormat format) {
  if (!dawn_loaded()) return format;
  uint32_t f = uint32_t(format);
  for (const auto& pair : kDawnNorm16)
    if (pair[0] == f) return WGPUTextureFormat(pair[1]);
  if (f > WGPUTextureFormat_ASTC12x12UnormSrgb) return format;  // extensions: same range
  return WGPUTextureFormat(f - dawn_format_shift(f));
}

WGPUTextureFormat standard_format(WGPUTextureFormat native) {
  if (!dawn_loaded()) return native;
  if (uint32_t(native) > 0x00010000 && uint32_t(native) < 0x00050000) return native;
  for (uint32_t f = 0; f <= WGPUTextureFormat_ASTC12x12UnormSrgb; ++f)
    if (native_format(WGPUTextureFormat(f)) == native) return WGPUTextureFormat(f);
  return native;  // a Dawn-only format
}

WGPUFeatureName native_feature(WGPUFeatureName feature) {
  if (!dawn_loaded()) return feature;
  uint32_t f = uint32_t(feature);
  if (f < kDawnFeatureCount) return WGPUFeatureName(kDawnFeature[f]);
  if (f < 0x00010000) return WGPUFeatureName(0);  // a newer standard feature Dawn lacks
  return feature;
}

WGPUFeatureName standard_feature(WGPUFeatureName native) {
  if (!dawn_loaded()) return native;
  uint32_t n = uint32_t(native);
  if (n >= 0x00010000) return native;
  for (uint32_t i = 1; i < kDawnFeatureCount; ++i)
    if (kDawnFeature[i] == n) return WGPUFeatureName(i);
  return WGPUFeatureName(0);
}

namespace detail {
void missing_proc(const char* name) {
  std::fprintf(stderr, "stipple: the loaded WebGPU implementation has no %s\n", name);
  std::abort();
}
}  // namespace detail

}  // namespace stipple::gpu
