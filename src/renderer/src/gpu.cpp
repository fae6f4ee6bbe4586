#include "stipple/renderer/gpu.hpp"

#include <algorithm>
#include <cctype>
#include <cstdlib>
#include <cstring>
#include <thread>

#include "stipple/core/error.hpp"
#include "stipple/core/log.hpp"
#include "stipple/renderer/staging.hpp"
#include "webgpu_loader.hpp"

namespace stipple::gpu {

WGPUStringView to_view(std::string_view s) {
  return WGPUStringView{s.data(), s.size()};
}

std::string to_string(WGPUStringView s) {
  if (!s.data) return {};
  if (s.length == WGPU_STRLEN) return std::string(s.data);
  return std::string(s.data, s.length);
}

namespace {

const char* graphics_api_name(WGPUBackendType type) {
  switch (type) {
    case WGPUBackendType_Null:
      return "Null";
    case WGPUBackendType_WebGPU:
      return "WebGPU";
    case WGPUBackendType_D3D11:
      return "D3D11";
    case WGPUBackendType_D3D12:
      return "D3D12";
    case WGPUBackendType_Metal:
      return "Metal";
    case WGPUBackendType_Vulkan:
      return "Vulkan";
    case WGPUBackendType_OpenGL:
      return "OpenGL";
    case WGPUBackendType_OpenGLES:
      return "OpenGLES";
    default:
      return "unknown";
  }
}

const char* adapter_type_name(WGPUAdapterType type) {
  switch (type) {
    case WGPUAdapterType_DiscreteGPU:
      return "discrete GPU";
    case WGPUAdapterType_IntegratedGPU:
      return "integrated GPU";
    case WGPUAdapterType_CPU:
      return "CPU";
    default:
      return "unknown";
  }
}

}  // namespace

bool is_cpu_adapter(const AdapterDescription& d) {
  if (d.adapter_type == "CPU") return true;
  std::string names = d.vendor + " " + d.architecture + " " + d.device + " " + d.description;
  std::transform(names.begin(), names.end(), names.begin(),
                 [](unsigned char c) { return char(std::tolower(c)); });
  return names.find("swiftshader") != std::string::npos ||
         names.find("llvmpipe") != std::string::npos;
}

namespace {

const char* error_type_name(WGPUErrorType type) {
  switch (type) {
    case WGPUErrorType_Validation:
      return "validation error";
    case WGPUErrorType_OutOfMemory:
      return "out of memory";
    case WGPUErrorType_Internal:
      return "internal error";
    default:
      return "error";
  }
}

void on_uncaptured_error(WGPUDevice const*, WGPUErrorType type, WGPUStringView message,
                         void* userdata, void*) {
  auto* ctx = static_cast<Context*>(userdata);
  ctx->error_count++;
  ctx->last_error = fmt::format("{}: {}", error_type_name(type), to_string(message));
  STIPPLE_ERROR("WebGPU {}", ctx->last_error);
}

void on_device_lost(WGPUDevice const*, WGPUDeviceLostReason reason, WGPUStringView message,
                    void* userdata, void*) {
  auto* ctx = static_cast<Context*>(userdata);
  ctx->lost = true;
  // Destruction and shutdown are not failures.
  if (reason == WGPUDeviceLostReason_Destroyed || reason == WGPUDeviceLostReason_CallbackCancelled)
    return;
  STIPPLE_ERROR("WebGPU device lost: {}", to_string(message));
}

void on_wgpu_log(WGPULogLevel level, WGPUStringView message, void*) {
  std::string text = to_string(message);
  if (level == WGPULogLevel_Error)
    STIPPLE_ERROR("wgpu: {}", text);
  else if (level == WGPULogLevel_Warn)
    STIPPLE_DEBUG("wgpu: {}", text);
  else
    STIPPLE_TRACE("wgpu: {}", text);
}

// Dawn's WGPULimits (older header) has four more trailing members than ours; give every
// implementation room to write its own layout. Unset members read as "undefined" limits.
struct LimitsStorage {
  WGPULimits limits = WGPU_LIMITS_INIT;
  uint32_t trailing[16];
  LimitsStorage() { std::fill(std::begin(trailing), std::end(trailing), WGPU_LIMIT_U32_UNDEFINED); }
};

}  // namespace

WGPUTextureFormat native(WGPUTextureFormat format) {
  return native_format(format);
}

std::string feature_name(WGPUFeatureName feature) {
  switch (feature) {
    case WGPUFeatureName_CoreFeaturesAndLimits:
      return "core-features-and-limits";
    case WGPUFeatureName_DepthClipControl:
      return "depth-clip-control";
    case WGPUFeatureName_Depth32FloatStencil8:
      return "depth32float-stencil8";
    case WGPUFeatureName_TextureCompressionBC:
      return "texture-compression-bc";
    case WGPUFeatureName_TextureCompressionBCSliced3D:
      return "texture-compression-bc-sliced-3d";
    case WGPUFeatureName_TextureCompressionETC2:
      return "texture-compression-etc2";
    case WGPUFeatureName_TextureCompressionASTC:
      return "texture-compression-astc";
    case WGPUFeatureName_TextureCompressionASTCSliced3D:
      return "texture-compression-astc-sliced-3d";
    case WGPUFeatureName_TimestampQuery:
      return "timestamp-query";
    case WGPUFeatureName_IndirectFirstInstance:
      return "indirect-first-instance";
    case WGPUFeatureName_ShaderF16:
      return "shader-f16";
    case WGPUFeatureName_RG11B10UfloatRenderable:
      return "rg11b10ufloat-renderable";
    case WGPUFeatureName_BGRA8UnormStorage:
      return "bgra8unorm-storage";
    case WGPUFeatureName_Float32Filterable:
      return "float32-filterable";
    case WGPUFeatureName_Float32Blendable:
      return "float32-blendable";
    case WGPUFeatureName_ClipDistances:
      return "clip-distances";
    case WGPUFeatureName_DualSourceBlending:
      return "dual-source-blending";
    case WGPUFeatureName_Subgroups:
      return "subgroups";
    case WGPUFeatureName_TextureFormatsTier1:
      return "texture-formats-tier1";
    case WGPUFeatureName_TextureFormatsTier2:
      return "texture-formats-tier2";
    case WGPUFeatureName_PrimitiveIndex:
      return "primitive-index";
    case WGPUFeatureName_TextureComponentSwizzle:
      return "texture-component-swizzle";
    default:
      break;
  }
  uint32_t value = uint32_t(feature);
  // wgpu-native's own features live at 0x0003xxxx (wgpu.h), Dawn's at 0x0005xxxx.
  switch (value) {
    case WGPUNativeFeature_Immediates:
      return "wgpu:immediates";
    case WGPUNativeFeature_TimestampQueryInsideEncoders:
      return "wgpu:timestamp-query-inside-encoders";
    case WGPUNativeFeature_TimestampQueryInsidePasses:
      return "wgpu:timestamp-query-inside-passes";
    case WGPUNativeFeature_ShaderF64:
      return "wgpu:shader-f64";
    case WGPUNativeFeature_ShaderI16:
      return "wgpu:shader-i16";
    case WGPUNativeFeature_Subgroup:
      return "wgpu:subgroup";
    case WGPUNativeFeature_MultiDrawIndirectCount:
      return "wgpu:multi-draw-indirect-count";
    case WGPUNativeFeature_PipelineStatisticsQuery:
      return "wgpu:pipeline-statistics-query";
    case WGPUNativeFeature_VertexWritableStorage:
      return "wgpu:vertex-writable-storage";
    case WGPUNativeFeature_PolygonModeLine:
      return "wgpu:polygon-mode-line";
    case WGPUNativeFeature_PolygonModePoint:
      return "wgpu:polygon-mode-point";
    case WGPUNativeFeature_ConservativeRasterization:
      return "wgpu:conservative-rasterization";
    case WGPUNativeFeature_ShaderEarlyDepthTest:
      return "wgpu:shader-early-depth-test";
    case WGPUNativeFeature_ShaderInt64:
      return "wgpu:shader-int64";
    case WGPUNativeFeature_ShaderInt64AtomicMinMax:
      return "wgpu:shader-int64-atomic-min-max";
    case WGPUNativeFeature_ShaderInt64AtomicAllOps:
      return "wgpu:shader-int64-atomic-all-ops";
    case uint32_t(kFeatureAtomicVec2uMinMax):
      return "atomic-vec2u-min-max";
    default:
      break;
  }
  const char* family = (value >> 16) == 3 ? "wgpu" : (value >> 16) == 5 ? "dawn" : "unknown";
  return fmt::format("{}:0x{:08x}", family, value);
}

std::vector<std::pair<std::string, uint64_t>> limit_list(const WGPULimits& l) {
  return {
      {"maxTextureDimension1D", l.maxTextureDimension1D},
      {"maxTextureDimension2D", l.maxTextureDimension2D},
      {"maxTextureDimension3D", l.maxTextureDimension3D},
      {"maxTextureArrayLayers", l.maxTextureArrayLayers},
      {"maxBindGroups", l.maxBindGroups},
      {"maxBindGroupsPlusVertexBuffers", l.maxBindGroupsPlusVertexBuffers},
      {"maxBindingsPerBindGroup", l.maxBindingsPerBindGroup},
      {"maxDynamicUniformBuffersPerPipelineLayout", l.maxDynamicUniformBuffersPerPipelineLayout},
      {"maxDynamicStorageBuffersPerPipelineLayout", l.maxDynamicStorageBuffersPerPipelineLayout},
      {"maxSampledTexturesPerShaderStage", l.maxSampledTexturesPerShaderStage},
      {"maxSamplersPerShaderStage", l.maxSamplersPerShaderStage},
      {"maxStorageBuffersPerShaderStage", l.maxStorageBuffersPerShaderStage},
      {"maxStorageTexturesPerShaderStage", l.maxStorageTexturesPerShaderStage},
      {"maxUniformBuffersPerShaderStage", l.maxUniformBuffersPerShaderStage},
      {"maxUniformBufferBindingSize", l.maxUniformBufferBindingSize},
      {"maxStorageBufferBindingSize", l.maxStorageBufferBindingSize},
      {"minUniformBufferOffsetAlignment", l.minUniformBufferOffsetAlignment},
      {"minStorageBufferOffsetAlignment", l.minStorageBufferOffsetAlignment},
      {"maxVertexBuffers", l.maxVertexBuffers},
      {"maxBufferSize", l.maxBufferSize},
      {"maxVertexAttributes", l.maxVertexAttributes},
      {"maxVertexBufferArrayStride", l.maxVertexBufferArrayStride},
      {"maxInterStageShaderVariables", l.maxInterStageShaderVariables},
      {"maxColorAttachments", l.maxColorAttachments},
      {"maxColorAttachmentBytesPerSample", l.maxColorAttachmentBytesPerSample},
      {"maxComputeWorkgroupStorageSize", l.maxComputeWorkgroupStorageSize},
      {"maxComputeInvocationsPerWorkgroup", l.maxComputeInvocationsPerWorkgroup},
      {"maxComputeWorkgroupSizeX", l.maxComputeWorkgroupSizeX},
      {"maxComputeWorkgroupSizeY", l.maxComputeWorkgroupSizeY},
      {"maxComputeWorkgroupSizeZ", l.maxComputeWorkgroupSizeZ},
      {"maxComputeWorkgroupsPerDimension", l.maxComputeWorkgroupsPerDimension},
  };
}

bool Context::has_feature(WGPUFeatureName feature) const {
  return std::find(features.begin(), features.end(), feature) != features.end();
}

void Context::poll(bool wait) {
#ifdef __EMSCRIPTEN__
  // In the browser, callbacks come from its event loop, and processing events yields the page's
  // thread to it (a task, not free): a poll that must not wait leaves them to the page's next
  // animation frame, when it yields anyway.
  if (!wait) return;
#endif
  // wgpu-native fires map and work-done callbacks from wgpuDevicePoll; Dawn from
  // wgpuInstanceProcessEvents. Calling both is harmless where one is a no-op.
  if (device && has_proc("wgpuDevicePoll")) wgpuDevicePoll(device.get(), wait, nullptr);
  wgpuInstanceProcessEvents(instance.get());
  if (wait) std::this_thread::yield();
}

void Context::wait_idle() {
  bool done = false;
  WGPUQueueWorkDoneCallbackInfo info = WGPU_QUEUE_WORK_DONE_CALLBACK_INFO_INIT;
  info.mode = WGPUCallbackMode_AllowProcessEvents;
  info.callback = [](WGPUQueueWorkDoneStatus, WGPUStringView, void* done, void*) {
    *static_cast<bool*>(done) = true;
  };
  info.userdata1 = &done;
  wgpuQueueOnSubmittedWorkDone(queue.get(), info);
  wait_until([&] { return done || lost; });
}

void Context::check(std::string_view what) {
  if (lost) fail("WebGPU device lost while {}", what);
  if (error_count > 0) {
    std::string message = last_error;
    error_count = 0;
    last_error.clear();
    fail("WebGPU {} while {}", message, what);
  }
}

Context::~Context() {
  // Release in dependency order while every member is alive: callbacks may fire here.
  queue.reset();
  device.reset();
  adapter.reset();
  if (instance) wgpuInstanceProcessEvents(instance.get());
  instance.reset();
}

std::unique_ptr<Context> create_context(const ContextOptions& options) {
  Backend backend = options.backend.empty() ? default_backend() : parse_backend(options.backend);
  load_backend(backend);
  if (has_proc("wgpuSetLogCallback") && has_proc("wgpuSetLogLevel")) {
    wgpuSetLogCallback(on_wgpu_log, nullptr);
    wgpuSetLogLevel(WGPULogLevel_Warn);
  }

  auto ctx = std::make_unique<Context>();
  WGPUInstanceDescriptor instance_desc = WGPU_INSTANCE_DESCRIPTOR_INIT;
  ctx->instance = Instance(wgpuCreateInstance(&instance_desc));
  if (!ctx->instance) fail("{}: could not create a WebGPU instance", backend_name(backend));

  struct AdapterResult {
    bool done = false;
    WGPUAdapter adapter = nullptr;
    std::string message;
  } adapter_result;
  WGPURequestAdapterOptions adapter_options = WGPU_REQUEST_ADAPTER_OPTIONS_INIT;
  adapter_options.powerPreference =
      options.low_power ? WGPUPowerPreference_LowPower : WGPUPowerPreference_HighPerformance;
  WGPURequestAdapterCallbackInfo adapter_cb = WGPU_REQUEST_ADAPTER_CALLBACK_INFO_INIT;
  adapter_cb.mode = WGPUCallbackMode_AllowProcessEvents;
  adapter_cb.callback = [](WGPURequestAdapterStatus status, WGPUAdapter adapter,
                           WGPUStringView message, void* userdata, void*) {
    auto* r = static_cast<AdapterResult*>(userdata);
    r->done = true;
    if (status == WGPURequestAdapterStatus_Success)
      r->adapter = adapter;
    else
      r->message = to_string(message);
  };
  adapter_cb.userdata1 = &adapter_result;
#ifdef __EMSCRIPTEN__
  // Chromium 156 with ANGLE on Vulkan (an NVIDIA GPU, headless) answers a page's first request
  // with null ("A valid external Instance reference no longer exists.") and the next with the
  // GPU's adapter (bench/RESULTS.md, "The page on a GPU"): ask again before giving up.
  constexpr int kAdapterRequests = 4;
#else
  constexpr int kAdapterRequests = 1;
#endif
  for (int request = 0; request < kAdapterRequests && !adapter_result.adapter; ++request) {
    adapter_result = AdapterResult{};
    wgpuInstanceRequestAdapter(ctx->instance.get(), &adapter_options, adapter_cb);
    ctx->wait_until([&] { return adapter_result.done; });
  }
  if (!adapter_result.adapter) {
#ifdef __EMSCRIPTEN__
    fail("the browser offers no WebGPU adapter ({}): is WebGPU enabled (chrome://gpu)?",
         adapter_result.message);
#endif
    fail(
        "{}: no WebGPU adapter found ({}). A Vulkan driver is needed: Mesa's lavapipe "
        "(mesa-vulkan-drivers 25 from bookworm-backports) or a GPU driver",
        backend_name(backend), adapter_result.message);
  }
  ctx->adapter = Adapter(adapter_result.adapter);

  WGPUAdapterInfo info = WGPU_ADAPTER_INFO_INIT;
  if (wgpuAdapterGetInfo(ctx->adapter.get(), &info) == WGPUStatus_Success) {
    auto& d = ctx->description;
    d.vendor = to_string(info.vendor);
    d.architecture = to_string(info.architecture);
    d.device = to_string(info.device);
    d.description = to_string(info.description);
    d.graphics_api = graphics_api_name(info.backendType);
    d.adapter_type = adapter_type_name(info.adapterType);
    d.vendor_id = info.vendorID;
    d.device_id = info.deviceID;
    wgpuAdapterInfoFreeMembers(info);
  }
  ctx->description.backend = std::string(backend_name(backend));

  LimitsStorage adapter_limits;
  if (wgpuAdapterGetLimits(ctx->adapter.get(), &adapter_limits.limits) != WGPUStatus_Success)
    fail("{}: could not read the adapter's limits", backend_name(backend));

  WGPUSupportedFeatures supported = WGPU_SUPPORTED_FEATURES_INIT;
  wgpuAdapterGetFeatures(ctx->adapter.get(), &supported);
  for (size_t i = 0; i < supported.featureCount; ++i)
    ctx->adapter_features.push_back(standard_feature(supported.features[i]));
  wgpuSupportedFeaturesFreeMembers(supported);

  std::vector<WGPUFeatureName> wanted = options.optional_features;
  wanted.push_back(WGPUFeatureName_TimestampQuery);
  for (WGPUFeatureName f : wanted) {
    bool available = std::find(ctx->adapter_features.begin(), ctx->adapter_features.end(), f) !=
                     ctx->adapter_features.end();
    if (available && !ctx->has_feature(f)) ctx->features.push_back(f);
  }

  struct DeviceResult {
    bool done = false;
    WGPUDevice device = nullptr;
    std::string message;
  } device_result;
  WGPUDeviceDescriptor device_desc = WGPU_DEVICE_DESCRIPTOR_INIT;
  device_desc.label = to_view("stipple");
  std::vector<WGPUFeatureName> native_features;
  for (WGPUFeatureName f : ctx->features) native_features.push_back(native_feature(f));
  device_desc.requiredFeatureCount = native_features.size();
  device_desc.requiredFeatures = native_features.data();
  device_desc.requiredLimits = &adapter_limits.limits;
  device_desc.deviceLostCallbackInfo.mode = WGPUCallbackMode_AllowProcessEvents;
  device_desc.deviceLostCallbackInfo.callback = on_device_lost;
  device_desc.deviceLostCallbackInfo.userdata1 = ctx.get();
  device_desc.uncapturedErrorCallbackInfo.callback = on_uncaptured_error;
  device_desc.uncapturedErrorCallbackInfo.userdata1 = ctx.get();
  WGPURequestDeviceCallbackInfo device_cb = WGPU_REQUEST_DEVICE_CALLBACK_INFO_INIT;
  device_cb.mode = WGPUCallbackMode_AllowProcessEvents;
  device_cb.callback = [](WGPURequestDeviceStatus status, WGPUDevice device, WGPUStringView message,
                          void* userdata, void*) {
    auto* r = static_cast<DeviceResult*>(userdata);
    r->done = true;
    if (status == WGPURequestDeviceStatus_Success)
      r->device = device;
    else
      r->message = to_string(message);
  };
  device_cb.userdata1 = &device_result;
  wgpuAdapterRequestDevice(ctx->adapter.get(), &device_desc, device_cb);
  ctx->wait_until([&] { return device_result.done; });
  if (!device_result.device)
    fail("{}: could not create a WebGPU device: {}", backend_name(backend), device_result.message);
  ctx->device = Device(device_result.device);
  // What the device really has (may be more than asked for).
  LimitsStorage device_limits;
  ctx->limits = wgpuDeviceGetLimits(ctx->device.get(), &device_limits.limits) == WGPUStatus_Success
                    ? device_limits.limits
                    : adapter_limits.limits;
  ctx->queue = Queue(wgpuDeviceGetQueue(ctx->device.get()));
  STIPPLE_DEBUG("WebGPU {} on {} ({}, {})", backend_name(backend), ctx->description.device,
                ctx->description.graphics_api, ctx->description.adapter_type);
  return ctx;
}

Buffer create_buffer(Context& ctx, uint64_t size, WGPUBufferUsage usage, std::string_view label,
                     const void* data) {
  WGPUBufferDescriptor desc = WGPU_BUFFER_DESCRIPTOR_INIT;
  desc.label = to_view(label);
  desc.size = (size + 3) & ~uint64_t(3);
  desc.usage = usage | (data ? WGPUBufferUsage_CopyDst : WGPUBufferUsage_None);
  if (desc.size > ctx.limits.maxBufferSize)
    fail("buffer '{}' of {} bytes exceeds the device's maxBufferSize ({})", label, desc.size,
         ctx.limits.maxBufferSize);
  Buffer buffer(wgpuDeviceCreateBuffer(ctx.device.get(), &desc));
  if (!buffer) fail("could not create buffer '{}' ({} bytes)", label, desc.size);
  if (data && size > 0) write_buffer(ctx, buffer.get(), 0, data, size);
  return buffer;
}

void write_buffer(Context& ctx, WGPUBuffer buffer, uint64_t offset, const void* data,
                  uint64_t size) {
  // writeBuffer takes multiples of 4 bytes: a ragged tail goes as one zero-padded word.
  const uint64_t whole = size & ~uint64_t(3);
  if (whole) wgpuQueueWriteBuffer(ctx.queue.get(), buffer, offset, data, whole);
  if (whole != size) {
    uint8_t tail[4] = {};
    std::memcpy(tail, static_cast<const uint8_t*>(data) + whole, size - whole);
    wgpuQueueWriteBuffer(ctx.queue.get(), buffer, offset + whole, tail, 4);
  }
}

BindGroup create_bind_group(Context& ctx, WGPUBindGroupLayout layout,
                            std::span<const Binding> bindings, std::string_view label) {
  std::vector<WGPUBindGroupEntry> entries(bindings.size(), WGPU_BIND_GROUP_ENTRY_INIT);
  for (size_t i = 0; i < bindings.size(); ++i) {
    entries[i].binding = bindings[i].binding;
    entries[i].buffer = bindings[i].buffer;
    entries[i].offset = bindings[i].offset;
    entries[i].size = bindings[i].size;
    entries[i].textureView = bindings[i].view;
    entries[i].sampler = bindings[i].sampler;
  }
  WGPUBindGroupDescriptor desc = WGPU_BIND_GROUP_DESCRIPTOR_INIT;
  desc.label = to_view(label);
  desc.layout = layout;
  desc.entryCount = entries.size();
  desc.entries = entries.data();
  return BindGroup(wgpuDeviceCreateBindGroup(ctx.device.get(), &desc));
}

namespace {
// A stage's pipeline-overridable constants, as the descriptors take them (keys borrow the
// names).
std::vector<WGPUConstantEntry> constant_entries(std::span<const PipelineConstant> constants) {
  std::vector<WGPUConstantEntry> entries(constants.size(), WGPU_CONSTANT_ENTRY_INIT);
  for (size_t i = 0; i < constants.size(); ++i) {
    entries[i].key = to_view(constants[i].name);
    entries[i].value = constants[i].value;
  }
  return entries;
}
}  // namespace

ComputePipeline create_compute_pipeline(Context& ctx, WGPUShaderModule module,
                                        std::string_view entry, WGPUPipelineLayout layout,
                                        std::string_view label,
                                        std::span<const PipelineConstant> constants) {
  WGPUComputePipelineDescriptor desc = WGPU_COMPUTE_PIPELINE_DESCRIPTOR_INIT;
  desc.label = to_view(label);
  desc.layout = layout;
  desc.compute.module = module;
  desc.compute.entryPoint = to_view(entry);
  const std::vector<WGPUConstantEntry> entries = constant_entries(constants);
  desc.compute.constantCount = entries.size();
  desc.compute.constants = entries.empty() ? nullptr : entries.data();
  return ComputePipeline(wgpuDeviceCreateComputePipeline(ctx.device.get(), &desc));
}

BindGroupLayout create_compute_layout(Context& ctx, std::initializer_list<BufferBinding> bindings,
                                      std::string_view label) {
  std::vector<WGPUBindGroupLayoutEntry> entries;
  for (BufferBinding b : bindings) {
    WGPUBindGroupLayoutEntry e = WGPU_BIND_GROUP_LAYOUT_ENTRY_INIT;
    e.binding = uint32_t(entries.size());
    e.visibility = WGPUShaderStage_Compute;
    e.buffer.type = b == BufferBinding::Uniform           ? WGPUBufferBindingType_Uniform
                    : b == BufferBinding::ReadOnlyStorage ? WGPUBufferBindingType_ReadOnlyStorage
                                                          : WGPUBufferBindingType_Storage;
    entries.push_back(e);
  }
  WGPUBindGroupLayoutDescriptor desc = WGPU_BIND_GROUP_LAYOUT_DESCRIPTOR_INIT;
  desc.label = to_view(label);
  desc.entryCount = entries.size();
  desc.entries = entries.data();
  return BindGroupLayout(wgpuDeviceCreateBindGroupLayout(ctx.device.get(), &desc));
}

PipelineLayout create_pipeline_layout(Context& ctx,
                                      std::initializer_list<WGPUBindGroupLayout> groups) {
  std::vector<WGPUBindGroupLayout> layouts(groups);
  WGPUPipelineLayoutDescriptor desc = WGPU_PIPELINE_LAYOUT_DESCRIPTOR_INIT;
  desc.bindGroupLayoutCount = layouts.size();
  desc.bindGroupLayouts = layouts.data();
  return PipelineLayout(wgpuDeviceCreatePipelineLayout(ctx.device.get(), &desc));
}

BindGroupLayout bind_group_layout_of(const ComputePipeline& pipeline, uint32_t group) {
  return BindGroupLayout(wgpuComputePipelineGetBindGroupLayout(pipeline.get(), group));
}

BindGroupLayout bind_group_layout_of(const RenderPipeline& pipeline, uint32_t group) {
  return BindGroupLayout(wgpuRenderPipelineGetBindGroupLayout(pipeline.get(), group));
}

RenderPipeline create_fullscreen_pipeline(Context& ctx, const FullscreenPipelineDesc& d) {
  WGPUColorTargetState target = WGPU_COLOR_TARGET_STATE_INIT;
  target.format = native(d.format);
  target.writeMask = WGPUColorWriteMask_All;
  target.blend = d.blend;
  WGPUFragmentState fragment = WGPU_FRAGMENT_STATE_INIT;
  fragment.module = d.module;
  fragment.entryPoint = to_view(d.fragment_entry);
  fragment.targetCount = 1;
  fragment.targets = &target;
  const std::vector<WGPUConstantEntry> entries = constant_entries(d.constants);
  fragment.constantCount = entries.size();
  fragment.constants = entries.empty() ? nullptr : entries.data();
  WGPURenderPipelineDescriptor desc = WGPU_RENDER_PIPELINE_DESCRIPTOR_INIT;
  desc.label = to_view(d.label);
  desc.layout = d.layout;
  desc.vertex.module = d.module;
  desc.vertex.entryPoint = to_view(d.vertex_entry);
  desc.primitive.topology = WGPUPrimitiveTopology_TriangleList;
  desc.multisample.count = 1;
  desc.multisample.mask = ~0u;
  desc.fragment = &fragment;
  return RenderPipeline(wgpuDeviceCreateRenderPipeline(ctx.device.get(), &desc));
}

void dispatch(WGPUComputePassEncoder pass, WGPUComputePipeline pipeline,
              std::initializer_list<BoundGroup> groups, uint32_t x, uint32_t y, uint32_t z) {
  wgpuComputePassEncoderSetPipeline(pass, pipeline);
  uint32_t index = 0;
  for (const BoundGroup& g : groups)
    wgpuComputePassEncoderSetBindGroup(pass, index++, g.group, g.offsets.size(), g.offsets.data());
  wgpuComputePassEncoderDispatchWorkgroups(pass, x, y, z);
}

void set_bind_groups(WGPURenderPassEncoder pass, std::initializer_list<BoundGroup> groups) {
  uint32_t index = 0;
  for (const BoundGroup& g : groups)
    wgpuRenderPassEncoderSetBindGroup(pass, index++, g.group, g.offsets.size(), g.offsets.data());
}

Texture create_texture_2d(Context& ctx, uint32_t width, uint32_t height, WGPUTextureFormat format,
                          WGPUTextureUsage usage, std::string_view label) {
  uint32_t max = ctx.limits.maxTextureDimension2D;
  if (width == 0 || height == 0 || width > max || height > max)
    fail("texture '{}' of {}x{} is outside the device's limits (1..{})", label, width, height, max);
  WGPUTextureDescriptor desc = WGPU_TEXTURE_DESCRIPTOR_INIT;
  desc.label = to_view(label);
  desc.size = {width, height, 1};
  desc.format = native_format(format);
  desc.usage = usage;
  desc.dimension = WGPUTextureDimension_2D;
  desc.mipLevelCount = 1;
  desc.sampleCount = 1;
  return Texture(wgpuDeviceCreateTexture(ctx.device.get(), &desc));
}

TextureView create_view(const Texture& texture) {
  return TextureView(wgpuTextureCreateView(texture.get(), nullptr));
}

ShaderModule create_shader(Context& ctx, std::string_view wgsl, std::string_view label,
                           const std::function<std::string(std::string_view)>& map_message,
                           bool trusted) {
  WGPUShaderSourceWGSL source = WGPU_SHADER_SOURCE_WGSL_INIT;
  source.code = to_view(wgsl);
  WGPUShaderModuleDescriptor desc = WGPU_SHADER_MODULE_DESCRIPTOR_INIT;
  desc.nextInChain = &source.chain;
  desc.label = to_view(label);
  struct ScopeResult {
    bool done = false;
    WGPUErrorType type = WGPUErrorType_NoError;
    std::string message;
  } scope;
  wgpuDevicePushErrorScope(ctx.device.get(), WGPUErrorFilter_Validation);
  // STIPPLE_SHADER_CHECKS=off / on (wgpu-native only): every shader without naga's inserted
  // bounds checks, or every shader with them (trusted ones too); the driver's robust buffer
  // access stays either way.
  static const int checks = [] {
    const char* env = std::getenv("STIPPLE_SHADER_CHECKS");
    if (!env) return 0;
    return std::string_view(env) == "off" ? -1 : std::string_view(env) == "on" ? 1 : 0;
  }();
  const bool unchecked = checks < 0 || (checks == 0 && trusted);
  ShaderModule module(unchecked && has_proc("wgpuDeviceCreateShaderModuleTrusted")
                          ? wgpuDeviceCreateShaderModuleTrusted(ctx.device.get(), &desc,
                                                                WGPUShaderRuntimeChecks_None)
                          : wgpuDeviceCreateShaderModule(ctx.device.get(), &desc));
  WGPUPopErrorScopeCallbackInfo cb = WGPU_POP_ERROR_SCOPE_CALLBACK_INFO_INIT;
  cb.mode = WGPUCallbackMode_AllowProcessEvents;
  cb.callback = [](WGPUPopErrorScopeStatus, WGPUErrorType type, WGPUStringView message,
                   void* userdata, void*) {
    auto* r = static_cast<ScopeResult*>(userdata);
    r->done = true;
    r->type = type;
    r->message = to_string(message);
  };
  cb.userdata1 = &scope;
  wgpuDevicePopErrorScope(ctx.device.get(), cb);
  ctx.wait_until([&] { return scope.done || ctx.lost; });
  if (scope.type != WGPUErrorType_NoError || !module)
    fail("shader '{}' failed to compile:\n{}", label,
         map_message ? map_message(scope.message) : scope.message);
  return module;
}

std::vector<uint8_t> read_buffer(Context& ctx, WGPUBuffer buffer, uint64_t offset, uint64_t size) {
  ReadbackBuffer once;  // read_back's path, with a buffer of its own
  std::vector<uint8_t> result(size);
  read_back(ctx, once, buffer, offset, size, result.data());
  return result;
}

Image read_texture(Context& ctx, WGPUTexture texture, uint32_t width, uint32_t height,
                   WGPUTextureFormat format) {
  const uint32_t row_bytes = width * 4;
  const uint32_t row_stride = (row_bytes + 255) & ~255u;  // bytesPerRow must be 256-aligned
  uint64_t size = uint64_t(row_stride) * height;
  Buffer staging =
      create_buffer(ctx, size, WGPUBufferUsage_CopySrc | WGPUBufferUsage_CopyDst, "texture-copy");
  WGPUCommandEncoderDescriptor enc_desc = WGPU_COMMAND_ENCODER_DESCRIPTOR_INIT;
  CommandEncoder encoder(wgpuDeviceCreateCommandEncoder(ctx.device.get(), &enc_desc));
  WGPUTexelCopyTextureInfo src = WGPU_TEXEL_COPY_TEXTURE_INFO_INIT;
  src.texture = texture;
  WGPUTexelCopyBufferInfo dst = WGPU_TEXEL_COPY_BUFFER_INFO_INIT;
  dst.buffer = staging.get();
  dst.layout.bytesPerRow = row_stride;
  dst.layout.rowsPerImage = height;
  WGPUExtent3D extent = {width, height, 1};
  wgpuCommandEncoderCopyTextureToBuffer(encoder.get(), &src, &dst, &extent);
  CommandBuffer commands(wgpuCommandEncoderFinish(encoder.get(), nullptr));
  WGPUCommandBuffer raw = commands.get();
  wgpuQueueSubmit(ctx.queue.get(), 1, &raw);
  std::vector<uint8_t> bytes = read_buffer(ctx, staging.get(), 0, size);

  Image image{width, height, std::vector<uint8_t>(size_t(width) * height * 4)};
  bool bgra = format == WGPUTextureFormat_BGRA8Unorm || format == WGPUTextureFormat_BGRA8UnormSrgb;
  for (uint32_t y = 0; y < height; ++y) {
    const uint8_t* src_row = bytes.data() + size_t(y) * row_stride;
    uint8_t* dst_row = image.rgba.data() + size_t(y) * row_bytes;
    std::memcpy(dst_row, src_row, row_bytes);
    if (bgra)
      for (uint32_t x = 0; x < width; ++x) std::swap(dst_row[x * 4], dst_row[x * 4 + 2]);
  }
  return image;
}

OffscreenTarget create_offscreen_target(Context& ctx, uint32_t width, uint32_t height) {
  OffscreenTarget t;
  t.width = width;
  t.height = height;
  t.color = create_texture_2d(ctx, width, height, t.color_format,
                              WGPUTextureUsage_RenderAttachment | WGPUTextureUsage_CopySrc |
                                  WGPUTextureUsage_TextureBinding | WGPUTextureUsage_StorageBinding,
                              "offscreen-color");
  t.depth = create_texture_2d(ctx, width, height, t.depth_format,
                              WGPUTextureUsage_RenderAttachment | WGPUTextureUsage_TextureBinding,
                              "offscreen-depth");
  t.color_view = create_view(t.color);
  t.depth_view = create_view(t.depth);
  return t;
}

}  // namespace stipple::gpu
