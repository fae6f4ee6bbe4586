#pragma once
// A small RAII layer over webgpu.h: handles, the device context, buffer/texture/pipeline
// helpers, synchronous readback and an offscreen target.
#include <cstdint>
#include <functional>
#include <initializer_list>
#include <memory>
#include <span>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include <webgpu/webgpu.h>

namespace stipple::gpu {

enum class Backend;

// Unique ownership of one WebGPU object; releases it on destruction.
template <typename T, void (*Release)(T)>
class Handle {
 public:
  Handle() = default;
  explicit Handle(T raw) : raw_(raw) {}
  Handle(Handle&& other) noexcept : raw_(std::exchange(other.raw_, nullptr)) {}
  Handle& operator=(Handle&& other) noexcept {
    if (this != &other) {
      reset();
      raw_ = std::exchange(other.raw_, nullptr);
    }
    return *this;
  }
  Handle(const Handle&) = delete;
  Handle& operator=(const Handle&) = delete;
  ~Handle() { reset(); }
  void reset() {
    if (raw_) Release(raw_);
    raw_ = nullptr;
  }
  T get() const { return raw_; }
  explicit operator bool() const { return raw_ != nullptr; }

 private:
  T raw_ = nullptr;
};

using Instance = Handle<WGPUInstance, wgpuInstanceRelease>;
using Adapter = Handle<WGPUAdapter, wgpuAdapterRelease>;
using Device = Handle<WGPUDevice, wgpuDeviceRelease>;
using Queue = Handle<WGPUQueue, wgpuQueueRelease>;
using Buffer = Handle<WGPUBuffer, wgpuBufferRelease>;
using Texture = Handle<WGPUTexture, wgpuTextureRelease>;
using TextureView = Handle<WGPUTextureView, wgpuTextureViewRelease>;
using Sampler = Handle<WGPUSampler, wgpuSamplerRelease>;
using ShaderModule = Handle<WGPUShaderModule, wgpuShaderModuleRelease>;
using BindGroupLayout = Handle<WGPUBindGroupLayout, wgpuBindGroupLayoutRelease>;
using BindGroup = Handle<WGPUBindGroup, wgpuBindGroupRelease>;
using PipelineLayout = Handle<WGPUPipelineLayout, wgpuPipelineLayoutRelease>;
using RenderPipeline = Handle<WGPURenderPipeline, wgpuRenderPipelineRelease>;
using ComputePipeline = Handle<WGPUComputePipeline, wgpuComputePipelineRelease>;
using CommandEncoder = Handle<WGPUCommandEncoder, wgpuCommandEncoderRelease>;
using CommandBuffer = Handle<WGPUCommandBuffer, wgpuCommandBufferRelease>;
using RenderPassEncoder = Handle<WGPURenderPassEncoder, wgpuRenderPassEncoderRelease>;
using ComputePassEncoder = Handle<WGPUComputePassEncoder, wgpuComputePassEncoderRelease>;
using QuerySet = Handle<WGPUQuerySet, wgpuQuerySetRelease>;

WGPUStringView to_view(std::string_view s);
// Every texture format written into a descriptor goes through native(): implementations built
// from different webgpu.h revisions number formats differently (see webgpu_loader.hpp).
WGPUTextureFormat native(WGPUTextureFormat format);
std::string to_string(WGPUStringView s);

struct ContextOptions {
  std::string backend;  // "dawn", "wgpu" or empty for the default (STIPPLE_BACKEND)
  bool low_power = false;
  // Features to enable when the adapter has them (missing ones are skipped, not an error).
  std::vector<WGPUFeatureName> optional_features;
};

struct AdapterDescription {
  std::string backend;  // the WebGPU implementation: "dawn" or "wgpu"
  std::string vendor, architecture, device, description;
  std::string graphics_api;  // "Vulkan", "Metal", ...
  std::string adapter_type;  // "discrete GPU", "CPU", ...
  uint32_t vendor_id = 0, device_id = 0;
};

// Whether the adapter runs on the CPU: its type says so, or (browsers report no type for it)
// its name is SwiftShader's or llvmpipe's.
bool is_cpu_adapter(const AdapterDescription& d);

// One device with its queue; limits are the adapter's own (WebGPU defaults are far too small
// for point clouds: 128 MiB storage bindings).
struct Context {
  Instance instance;
  Adapter adapter;
  Device device;
  Queue queue;
  AdapterDescription description;
  WGPULimits limits{};
  std::vector<WGPUFeatureName> features;  // enabled on the device
  std::vector<WGPUFeatureName> adapter_features;
  uint64_t error_count = 0;  // uncaptured errors seen (validation, out of memory, internal)
  std::string last_error;
  bool lost = false;

  Context() = default;
  Context(const Context&) = delete;
  Context& operator=(const Context&) = delete;
  ~Context();
  bool has_feature(WGPUFeatureName feature) const;
  // Runs the implementation's event processing until done() returns true.
  template <typename Predicate>
  void wait_until(Predicate done) {
    while (!done()) poll(true);
  }
  void poll(bool wait);
  // Waits for all submitted work to finish.
  void wait_idle();
  // Throws stipple::Error when an uncaptured error happened since the last check.
  void check(std::string_view what);
};

std::unique_ptr<Context> create_context(const ContextOptions& options = {});
std::string feature_name(WGPUFeatureName feature);
// WebGPU's "atomic-vec2u-min-max" (64-bit atomicStoreMin/Max on atomic<vec2u> in WGSL), under
// Dawn's number for it: the standard webgpu.h has none yet. Browsers offer it where the GPU has
// 64-bit atomics; the page's bridge (webgpu_web.cpp) reports and requests it by its name.
inline constexpr WGPUFeatureName kFeatureAtomicVec2uMinMax = WGPUFeatureName(0x0005003B);
// Human-readable "name value" lines for every limit, in the header's order.
std::vector<std::pair<std::string, uint64_t>> limit_list(const WGPULimits& limits);

// ---- helpers ------------------------------------------------------------------------------
Buffer create_buffer(Context& ctx, uint64_t size, WGPUBufferUsage usage, std::string_view label,
                     const void* data = nullptr);
Texture create_texture_2d(Context& ctx, uint32_t width, uint32_t height, WGPUTextureFormat format,
                          WGPUTextureUsage usage, std::string_view label);
TextureView create_view(const Texture& texture);
// Compiles WGSL; throws stipple::Error with the compiler's messages (file:line:column) on failure,
// passed through map_message when given (preprocessed sources map lines back to their files).
// `trusted`: a shader of ours whose indices are in range by construction, compiled without
// naga's inserted bounds checks where the implementation allows it (wgpu-native's
// wgpuDeviceCreateShaderModuleTrusted; the driver's robust buffer access stays). The compute
// rasterizer's batch passes are bound by the instructions they issue a point, and the checks
// are about a tenth of them. STIPPLE_SHADER_CHECKS=on keeps the checks everywhere, =off drops
// them everywhere.
ShaderModule create_shader(Context& ctx, std::string_view wgsl, std::string_view label,
                           const std::function<std::string(std::string_view)>& map_message = {},
                           bool trusted = false);

// Queues a write of `size` bytes at `offset` (a multiple of 4); `data` may be freed on return. A
// size that is not a multiple of 4 is padded with zeros to the next one, which the buffer must
// hold (create_buffer rounds sizes up so).
void write_buffer(Context& ctx, WGPUBuffer buffer, uint64_t offset, const void* data,
                  uint64_t size);
template <typename T>
void write_buffer(Context& ctx, WGPUBuffer buffer, uint64_t offset, const T& value) {
  write_buffer(ctx, buffer, offset, &value, sizeof(T));
}

// One entry of a bind group: a buffer range, a texture view or a sampler.
struct Binding {
  uint32_t binding = 0;
  WGPUBuffer buffer = nullptr;
  uint64_t offset = 0, size = WGPU_WHOLE_SIZE;
  WGPUTextureView view = nullptr;
  WGPUSampler sampler = nullptr;
};
inline Binding bind_buffer(uint32_t binding, WGPUBuffer buffer, uint64_t offset = 0,
                           uint64_t size = WGPU_WHOLE_SIZE) {
  return {binding, buffer, offset, size, nullptr, nullptr};
}
inline Binding bind_texture(uint32_t binding, WGPUTextureView view) {
  return {binding, nullptr, 0, WGPU_WHOLE_SIZE, view, nullptr};
}
inline Binding bind_sampler(uint32_t binding, WGPUSampler sampler) {
  return {binding, nullptr, 0, WGPU_WHOLE_SIZE, nullptr, sampler};
}
BindGroup create_bind_group(Context& ctx, WGPUBindGroupLayout layout,
                            std::span<const Binding> bindings, std::string_view label = {});
inline BindGroup create_bind_group(Context& ctx, WGPUBindGroupLayout layout,
                                   std::initializer_list<Binding> bindings,
                                   std::string_view label = {}) {
  return create_bind_group(ctx, layout, std::span(bindings.begin(), bindings.size()), label);
}

// A compute pipeline of one entry point; a null layout is derived from the shader. `constants`
// set the shader's pipeline-overridable constants (`override` declarations) by name.
struct PipelineConstant {
  std::string name;
  double value = 0.0;
};
ComputePipeline create_compute_pipeline(Context& ctx, WGPUShaderModule module,
                                        std::string_view entry, WGPUPipelineLayout layout,
                                        std::string_view label,
                                        std::span<const PipelineConstant> constants = {});

// An explicit layout of buffer bindings 0, 1, ... for compute shaders (one layout shared by
// entry points that use different subsets of the bindings), and a pipeline layout of groups.
enum class BufferBinding { Uniform, ReadOnlyStorage, Storage };
BindGroupLayout create_compute_layout(Context& ctx, std::initializer_list<BufferBinding> bindings,
                                      std::string_view label = {});
PipelineLayout create_pipeline_layout(Context& ctx,
                                      std::initializer_list<WGPUBindGroupLayout> groups);

// Bind group layout `group` of a pipeline whose layout was derived from its shader.
BindGroupLayout bind_group_layout_of(const ComputePipeline& pipeline, uint32_t group = 0);
BindGroupLayout bind_group_layout_of(const RenderPipeline& pipeline, uint32_t group = 0);

// A pipeline that draws one full-screen triangle (3 vertices, no vertex buffers) into a single
// colour target: resolves, post-processing, overlays.
struct FullscreenPipelineDesc {
  WGPUShaderModule module = nullptr;
  std::string_view vertex_entry = "vs_fullscreen";
  std::string_view fragment_entry = "fs_main";
  WGPUPipelineLayout layout = nullptr;  // null: derived from the shader
  WGPUTextureFormat format = WGPUTextureFormat_RGBA8Unorm;
  const WGPUBlendState* blend = nullptr;  // null: the fragment's colour replaces the target's
  std::string_view label;
  std::span<const PipelineConstant> constants = {};  // the fragment stage's overrides
};
RenderPipeline create_fullscreen_pipeline(Context& ctx, const FullscreenPipelineDesc& desc);

// A bind group as set on a pass encoder, with its dynamic offsets (if its layout has any).
struct BoundGroup {
  BoundGroup(WGPUBindGroup g) : group(g) {}  // NOLINT: plain groups convert implicitly
  BoundGroup(WGPUBindGroup g, std::span<const uint32_t> offsets) : group(g), offsets(offsets) {}
  WGPUBindGroup group = nullptr;
  std::span<const uint32_t> offsets;
};
// Sets `pipeline` and `groups` (at 0, 1, ...) and dispatches x * y * z workgroups.
void dispatch(WGPUComputePassEncoder pass, WGPUComputePipeline pipeline,
              std::initializer_list<BoundGroup> groups, uint32_t x, uint32_t y = 1, uint32_t z = 1);
// Sets `groups` at 0, 1, ... on a render pass.
void set_bind_groups(WGPURenderPassEncoder pass, std::initializer_list<BoundGroup> groups);

// Copies a buffer range to the CPU, blocking until done.
std::vector<uint8_t> read_buffer(Context& ctx, WGPUBuffer buffer, uint64_t offset, uint64_t size);

struct Image {
  uint32_t width = 0, height = 0;
  std::vector<uint8_t> rgba;  // tightly packed RGBA8, top row first
};
// Reads a RGBA8/BGRA8 texture back as RGBA8, blocking until done.
Image read_texture(Context& ctx, WGPUTexture texture, uint32_t width, uint32_t height,
                   WGPUTextureFormat format);

// An offscreen colour + depth target to render into without a window.
struct OffscreenTarget {
  uint32_t width = 0, height = 0;
  WGPUTextureFormat color_format = WGPUTextureFormat_RGBA8Unorm;
  WGPUTextureFormat depth_format = WGPUTextureFormat_Depth32Float;
  Texture color, depth;
  TextureView color_view, depth_view;
};
OffscreenTarget create_offscreen_target(Context& ctx, uint32_t width, uint32_t height);

}  // namespace stipple::gpu
