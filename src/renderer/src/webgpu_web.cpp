// The standard webgpu.h over emscripten 3.1.69's older one (the browser's WebGPU through
// library_webgpu.js). Differences absorbed here: strings as const char* (not WGPUStringView),
// callbacks with one userdata passed as arguments (not *CallbackInfo structs returning futures),
// statuses and most enums numbered differently (translated by name: webgpu_web_enums.hpp),
// *Flags as 32-bit typedefs, WGPUShaderModuleWGSLDescriptor, canvas surfaces by selector,
// the uncaptured-error callback set by a function, renamed structs (ProgrammableStage,
// Required/SupportedLimits, ImageCopy*). Events: the browser delivers callbacks from its event
// loop, so wgpuInstanceProcessEvents yields to it (emscripten_sleep under JSPI).
#include "webgpu_web.hpp"

#include "stipple/renderer/gpu.hpp"

#include <emscripten.h>
#include <cmath>

#include <cstdlib>
#include <cstring>
#include <initializer_list>
#include <mutex>
#include <optional>
#include <string>
#include <string_view>
#include <type_traits>
#include <unordered_map>
#include <vector>

// emscripten's webgpu.h, types only, in a namespace of its own (its names are the standard
// header's). Its functions in library_webgpu.js are reached under other names (stipple_em_*:
// the generated JS library copies them); the few that emscripten implements in C (libwebgpu:
// the instance, surface capabilities, freeing adapter info) are done here instead.
#pragma clang diagnostic push
#pragma clang diagnostic ignored "-Wmacro-redefined"
#undef WEBGPU_H_
#define WGPU_SKIP_DECLARATIONS
namespace em {
#include STIPPLE_EM_WEBGPU_H
}
#undef WGPU_SKIP_DECLARATIONS
#pragma clang diagnostic pop

namespace em {
#include "webgpu_web_enums.hpp"
}

#define STIPPLE_EM(name) extern "C" std::remove_pointer_t<em::WGPUProc##name> stipple_em_wgpu##name;
STIPPLE_EM(InstanceRequestAdapter)
STIPPLE_EM(InstanceCreateSurface)
STIPPLE_EM(AdapterGetInfo)
STIPPLE_EM(AdapterGetLimits)
STIPPLE_EM(AdapterEnumerateFeatures)
STIPPLE_EM(AdapterRequestDevice)
STIPPLE_EM(AdapterRelease)
STIPPLE_EM(DeviceSetUncapturedErrorCallback)
STIPPLE_EM(DeviceGetLimits)
STIPPLE_EM(DeviceGetQueue)
STIPPLE_EM(DeviceCreateBuffer)
STIPPLE_EM(DeviceCreateTexture)
STIPPLE_EM(DeviceCreateSampler)
STIPPLE_EM(DeviceCreateShaderModule)
STIPPLE_EM(DeviceCreateBindGroupLayout)
STIPPLE_EM(DeviceCreateBindGroup)
STIPPLE_EM(DeviceCreatePipelineLayout)
STIPPLE_EM(DeviceCreateComputePipeline)
STIPPLE_EM(DeviceCreateRenderPipeline)
STIPPLE_EM(DeviceCreateCommandEncoder)
STIPPLE_EM(DeviceCreateQuerySet)
STIPPLE_EM(DevicePushErrorScope)
STIPPLE_EM(DevicePopErrorScope)
STIPPLE_EM(DeviceRelease)
STIPPLE_EM(QueueSubmit)
STIPPLE_EM(QueueWriteBuffer)
STIPPLE_EM(QueueWriteTexture)
STIPPLE_EM(QueueOnSubmittedWorkDone)
STIPPLE_EM(QueueRelease)
STIPPLE_EM(BufferMapAsync)
STIPPLE_EM(BufferGetMappedRange)
STIPPLE_EM(BufferGetConstMappedRange)
STIPPLE_EM(BufferUnmap)
STIPPLE_EM(BufferDestroy)
STIPPLE_EM(BufferRelease)
STIPPLE_EM(TextureCreateView)
STIPPLE_EM(TextureRelease)
STIPPLE_EM(TextureViewRelease)
STIPPLE_EM(SamplerRelease)
STIPPLE_EM(ShaderModuleRelease)
STIPPLE_EM(BindGroupLayoutRelease)
STIPPLE_EM(BindGroupRelease)
STIPPLE_EM(PipelineLayoutRelease)
STIPPLE_EM(ComputePipelineGetBindGroupLayout)
STIPPLE_EM(ComputePipelineRelease)
STIPPLE_EM(RenderPipelineGetBindGroupLayout)
STIPPLE_EM(RenderPipelineRelease)
STIPPLE_EM(QuerySetRelease)
STIPPLE_EM(CommandEncoderBeginComputePass)
STIPPLE_EM(CommandEncoderBeginRenderPass)
STIPPLE_EM(CommandEncoderClearBuffer)
STIPPLE_EM(CommandEncoderCopyBufferToBuffer)
STIPPLE_EM(CommandEncoderCopyTextureToBuffer)
STIPPLE_EM(CommandEncoderResolveQuerySet)
STIPPLE_EM(CommandEncoderFinish)
STIPPLE_EM(CommandEncoderRelease)
STIPPLE_EM(CommandBufferRelease)
STIPPLE_EM(ComputePassEncoderSetPipeline)
STIPPLE_EM(ComputePassEncoderSetBindGroup)
STIPPLE_EM(ComputePassEncoderDispatchWorkgroups)
STIPPLE_EM(ComputePassEncoderDispatchWorkgroupsIndirect)
STIPPLE_EM(ComputePassEncoderEnd)
STIPPLE_EM(ComputePassEncoderRelease)
STIPPLE_EM(RenderPassEncoderSetPipeline)
STIPPLE_EM(RenderPassEncoderSetBindGroup)
STIPPLE_EM(RenderPassEncoderSetVertexBuffer)
STIPPLE_EM(RenderPassEncoderSetIndexBuffer)
STIPPLE_EM(RenderPassEncoderSetScissorRect)
STIPPLE_EM(RenderPassEncoderDraw)
STIPPLE_EM(RenderPassEncoderDrawIndexed)
STIPPLE_EM(RenderPassEncoderDrawIndirect)
STIPPLE_EM(RenderPassEncoderEnd)
STIPPLE_EM(RenderPassEncoderRelease)
STIPPLE_EM(SurfaceGetPreferredFormat)
STIPPLE_EM(SurfaceConfigure)
STIPPLE_EM(SurfaceUnconfigure)
STIPPLE_EM(SurfaceGetCurrentTexture)
STIPPLE_EM(SurfacePresent)
STIPPLE_EM(SurfaceRelease)
#undef STIPPLE_EM

namespace stipple::gpu::web {
namespace {

// Handles are the same opaque pointers on both sides.
template <typename To, typename From>
To h(From from) {
  return reinterpret_cast<To>(from);
}
#define EMH(type, value) h<em::WGPU##type>(value)

// Strings: the standard header's views are not NUL-terminated; the old one takes C strings.
// A Strings keeps the copies alive for the duration of one call.
struct Strings {
  std::vector<std::string> storage;
  Strings() { storage.reserve(64); }
  const char* operator()(WGPUStringView v) {
    if (!v.data) return nullptr;
    storage.emplace_back(v.length == WGPU_STRLEN ? std::string(v.data)
                                                 : std::string(v.data, v.length));
    return storage.back().c_str();
  }
};
WGPUStringView view(const char* s) {
  return s ? WGPUStringView{s, std::strlen(s)} : WGPUStringView{nullptr, 0};
}
template <typename Flags>
uint32_t flags(Flags f) {
  return uint32_t(f);
}

// One-shot callbacks: the standard callback and its two userdata travel in a heap record.
template <typename Info>
Info* keep(const Info& info) {
  return new Info(info);
}

// ---- instance and adapter -------------------------------------------------------------------
WGPUInstance CreateInstance(const WGPUInstanceDescriptor*) {
  return h<WGPUInstance>(uintptr_t(1));  // the browser has one instance: id 1
}

void InstanceProcessEvents(WGPUInstance) {
  // Callbacks arrive from the browser's event loop: give it a turn.
  emscripten_sleep(0);
}

WGPUFuture InstanceRequestAdapter(WGPUInstance instance, const WGPURequestAdapterOptions* options,
                                  WGPURequestAdapterCallbackInfo info) {
  em::WGPURequestAdapterOptions o{};
  if (options) {
    o.powerPreference = em::to_em(options->powerPreference);
    if (options->powerPreference == WGPUPowerPreference_Undefined)
      o.powerPreference = em::WGPUPowerPreference_Undefined;
    o.forceFallbackAdapter = options->forceFallbackAdapter;
  }
  stipple_em_wgpuInstanceRequestAdapter(
      EMH(Instance, instance), &o,
      [](em::WGPURequestAdapterStatus status, em::WGPUAdapter adapter, const char* message,
         void* userdata) {
        auto* i = static_cast<WGPURequestAdapterCallbackInfo*>(userdata);
        i->callback(em::from_em(status), h<WGPUAdapter>(adapter), view(message), i->userdata1,
                    i->userdata2);
        delete i;
      },
      keep(info));
  return WGPUFuture{0};
}

void InstanceRelease(WGPUInstance) {}

WGPUStatus AdapterGetInfo(WGPUAdapter adapter, WGPUAdapterInfo* info) {
  em::WGPUAdapterInfo e{};
  stipple_em_wgpuAdapterGetInfo(EMH(Adapter, adapter), &e);
  // The strings stay the browser's until wgpuAdapterInfoFreeMembers; the record keeps them.
  auto* kept = new em::WGPUAdapterInfo(e);
  WGPUChainedStruct* next = info->nextInChain;
  *info = WGPUAdapterInfo{};
  info->nextInChain = next;
  info->vendor = view(e.vendor);
  info->architecture = view(e.architecture);
  info->device = view(e.device);
  info->description = view(e.description);
  info->backendType = WGPUBackendType_WebGPU;
  info->adapterType = em::from_em(e.adapterType);
  info->vendorID = e.vendorID;
  info->deviceID = e.deviceID;
  // Recover the record from any of its strings at free time: keep a side table of one entry.
  static em::WGPUAdapterInfo* last = nullptr;
  if (last) {
    for (const char* text : {last->vendor, last->architecture, last->device, last->description})
      std::free(const_cast<char*>(text));
    delete last;
  }
  last = kept;
  return WGPUStatus_Success;
}

void AdapterInfoFreeMembers(WGPUAdapterInfo) {
  // The browser's strings are freed when the next info is read (AdapterGetInfo).
}

template <typename Std, typename Em>
void copy_limits(Std& s, const Em& e) {
#define STIPPLE_LIMIT(x) s.x = e.x;
  STIPPLE_LIMIT(maxTextureDimension1D)
  STIPPLE_LIMIT(maxTextureDimension2D)
  STIPPLE_LIMIT(maxTextureDimension3D)
  STIPPLE_LIMIT(maxTextureArrayLayers)
  STIPPLE_LIMIT(maxBindGroups)
  STIPPLE_LIMIT(maxBindGroupsPlusVertexBuffers)
  STIPPLE_LIMIT(maxBindingsPerBindGroup)
  STIPPLE_LIMIT(maxDynamicUniformBuffersPerPipelineLayout)
  STIPPLE_LIMIT(maxDynamicStorageBuffersPerPipelineLayout)
  STIPPLE_LIMIT(maxSampledTexturesPerShaderStage)
  STIPPLE_LIMIT(maxSamplersPerShaderStage)
  STIPPLE_LIMIT(maxStorageBuffersPerShaderStage)
  STIPPLE_LIMIT(maxStorageTexturesPerShaderStage)
  STIPPLE_LIMIT(maxUniformBuffersPerShaderStage)
  STIPPLE_LIMIT(maxUniformBufferBindingSize)
  STIPPLE_LIMIT(maxStorageBufferBindingSize)
  STIPPLE_LIMIT(minUniformBufferOffsetAlignment)
  STIPPLE_LIMIT(minStorageBufferOffsetAlignment)
  STIPPLE_LIMIT(maxVertexBuffers)
  STIPPLE_LIMIT(maxBufferSize)
  STIPPLE_LIMIT(maxVertexAttributes)
  STIPPLE_LIMIT(maxVertexBufferArrayStride)
  STIPPLE_LIMIT(maxInterStageShaderVariables)
  STIPPLE_LIMIT(maxColorAttachments)
  STIPPLE_LIMIT(maxColorAttachmentBytesPerSample)
  STIPPLE_LIMIT(maxComputeWorkgroupStorageSize)
  STIPPLE_LIMIT(maxComputeInvocationsPerWorkgroup)
  STIPPLE_LIMIT(maxComputeWorkgroupSizeX)
  STIPPLE_LIMIT(maxComputeWorkgroupSizeY)
  STIPPLE_LIMIT(maxComputeWorkgroupSizeZ)
  STIPPLE_LIMIT(maxComputeWorkgroupsPerDimension)
#undef STIPPLE_LIMIT
}

WGPUStatus AdapterGetLimits(WGPUAdapter adapter, WGPULimits* limits) {
  em::WGPUSupportedLimits e{};
  if (!stipple_em_wgpuAdapterGetLimits(EMH(Adapter, adapter), &e)) return WGPUStatus_Error;
  copy_limits(*limits, e.limits);
  return WGPUStatus_Success;
}

WGPUStatus DeviceGetLimits(WGPUDevice device, WGPULimits* limits) {
  em::WGPUSupportedLimits e{};
  if (!stipple_em_wgpuDeviceGetLimits(EMH(Device, device), &e)) return WGPUStatus_Error;
  copy_limits(*limits, e.limits);
  return WGPUStatus_Success;
}

// Features newer than emscripten's webgpu.h, by their names (it enumerates and requests only
// those its table names): gpu::kFeatureAtomicVec2uMinMax.
EM_JS(int, stipple_adapter_has_feature, (em::WGPUAdapter adapter, const char* name),
      { return WebGPU.mgrAdapter.get(adapter).features.has(UTF8ToString(name)) ? 1 : 0; });
// Adds the named feature to the adapter's next requestDevice (library_webgpu.js builds the
// descriptor from its own table, which drops it).
// clang-format off (it would space "=>" apart, which JS does not parse)
EM_JS(void, stipple_adapter_require_feature, (em::WGPUAdapter adapter, const char* name), {
  const a = WebGPU.mgrAdapter.get(adapter);
  const feature = UTF8ToString(name);
  const request = a.requestDevice.bind(a);
  a.requestDevice = function(desc) {
    const d = Object.assign({}, desc || {});
    d.requiredFeatures = (d.requiredFeatures || []).concat([feature]);
    return request(d);
  };
});
// clang-format on

void AdapterGetFeatures(WGPUAdapter adapter, WGPUSupportedFeatures* features) {
  size_t n = stipple_em_wgpuAdapterEnumerateFeatures(EMH(Adapter, adapter), nullptr);
  std::vector<em::WGPUFeatureName> found(n);
  stipple_em_wgpuAdapterEnumerateFeatures(EMH(Adapter, adapter), found.data());
  auto* out = static_cast<WGPUFeatureName*>(std::malloc(sizeof(WGPUFeatureName) * (n + 2)));
  size_t count = 0;
  for (em::WGPUFeatureName f : found) {
    WGPUFeatureName s = em::from_em(f);
    if (s != WGPUFeatureName_Force32) out[count++] = s;
  }
  if (stipple_adapter_has_feature(EMH(Adapter, adapter), "atomic-vec2u-min-max"))
    out[count++] = gpu::kFeatureAtomicVec2uMinMax;
  features->featureCount = count;
  features->features = out;
}

void SupportedFeaturesFreeMembers(WGPUSupportedFeatures features) {
  std::free(const_cast<WGPUFeatureName*>(features.features));
}

struct DeviceCallbacks {
  WGPUDeviceLostCallbackInfo lost;
  WGPUUncapturedErrorCallbackInfo error;
  WGPUDevice device = nullptr;
};

WGPUFuture AdapterRequestDevice(WGPUAdapter adapter, const WGPUDeviceDescriptor* desc,
                                WGPURequestDeviceCallbackInfo info) {
  Strings str;
  em::WGPUDeviceDescriptor d{};
  std::vector<em::WGPUFeatureName> features;
  em::WGPURequiredLimits limits{};
  // Lives as long as the device (the browser calls back with it).
  auto* callbacks = new DeviceCallbacks{};
  if (desc) {
    d.label = str(desc->label);
    for (size_t i = 0; i < desc->requiredFeatureCount; ++i) {
      if (desc->requiredFeatures[i] == gpu::kFeatureAtomicVec2uMinMax) {
        stipple_adapter_require_feature(EMH(Adapter, adapter), "atomic-vec2u-min-max");
        continue;
      }
      em::WGPUFeatureName f = em::to_em(desc->requiredFeatures[i]);
      if (f != em::WGPUFeatureName_Force32) features.push_back(f);
    }
    d.requiredFeatureCount = features.size();
    d.requiredFeatures = features.data();
    if (desc->requiredLimits) {
      // Undefined members ask for the default; the browser takes what the adapter offers.
      std::memset(&limits.limits, 0xff, sizeof(limits.limits));
      copy_limits(limits.limits, *desc->requiredLimits);
      d.requiredLimits = &limits;
    }
    callbacks->lost = desc->deviceLostCallbackInfo;
    callbacks->error = desc->uncapturedErrorCallbackInfo;
  }
  d.deviceLostCallback = [](em::WGPUDeviceLostReason reason, const char* message, void* userdata) {
    auto* c = static_cast<DeviceCallbacks*>(userdata);
    if (c->lost.callback)
      c->lost.callback(&c->device, em::from_em(reason), view(message), c->lost.userdata1,
                       c->lost.userdata2);
  };
  d.deviceLostUserdata = callbacks;
  struct Pending {
    WGPURequestDeviceCallbackInfo info;
    DeviceCallbacks* callbacks;
  };
  stipple_em_wgpuAdapterRequestDevice(
      EMH(Adapter, adapter), &d,
      [](em::WGPURequestDeviceStatus status, em::WGPUDevice device, const char* message,
         void* userdata) {
        auto* p = static_cast<Pending*>(userdata);
        if (device) {
          p->callbacks->device = h<WGPUDevice>(device);
          stipple_em_wgpuDeviceSetUncapturedErrorCallback(
              device,
              [](em::WGPUErrorType type, const char* message, void* userdata) {
                auto* c = static_cast<DeviceCallbacks*>(userdata);
                if (c->error.callback)
                  c->error.callback(&c->device, em::from_em(type), view(message),
                                    c->error.userdata1, c->error.userdata2);
              },
              p->callbacks);
        }
        p->info.callback(em::from_em(status), h<WGPUDevice>(device), view(message),
                         p->info.userdata1, p->info.userdata2);
        delete p;
      },
      new Pending{info, callbacks});
  return WGPUFuture{0};
}

void AdapterRelease(WGPUAdapter adapter) {
  stipple_em_wgpuAdapterRelease(EMH(Adapter, adapter));
}

// ---- device ---------------------------------------------------------------------------------
WGPUQueue DeviceGetQueue(WGPUDevice device) {
  return h<WGPUQueue>(stipple_em_wgpuDeviceGetQueue(EMH(Device, device)));
}

WGPUBuffer DeviceCreateBuffer(WGPUDevice device, const WGPUBufferDescriptor* desc) {
  Strings str;
  em::WGPUBufferDescriptor d{};
  d.label = str(desc->label);
  d.usage = flags(desc->usage);
  d.size = desc->size;
  d.mappedAtCreation = desc->mappedAtCreation;
  return h<WGPUBuffer>(stipple_em_wgpuDeviceCreateBuffer(EMH(Device, device), &d));
}

WGPUTexture DeviceCreateTexture(WGPUDevice device, const WGPUTextureDescriptor* desc) {
  Strings str;
  em::WGPUTextureDescriptor d{};
  d.label = str(desc->label);
  d.usage = flags(desc->usage);
  d.dimension = em::to_em(desc->dimension);
  d.size = {desc->size.width, desc->size.height, desc->size.depthOrArrayLayers};
  d.format = em::to_em(desc->format);
  d.mipLevelCount = desc->mipLevelCount;
  d.sampleCount = desc->sampleCount;
  std::vector<em::WGPUTextureFormat> formats;
  for (size_t i = 0; i < desc->viewFormatCount; ++i)
    formats.push_back(em::to_em(desc->viewFormats[i]));
  d.viewFormatCount = formats.size();
  d.viewFormats = formats.data();
  return h<WGPUTexture>(stipple_em_wgpuDeviceCreateTexture(EMH(Device, device), &d));
}

WGPUSampler DeviceCreateSampler(WGPUDevice device, const WGPUSamplerDescriptor* desc) {
  Strings str;
  em::WGPUSamplerDescriptor d{};
  d.addressModeU = d.addressModeV = d.addressModeW = em::WGPUAddressMode_ClampToEdge;
  d.magFilter = d.minFilter = em::WGPUFilterMode_Nearest;
  d.mipmapFilter = em::WGPUMipmapFilterMode_Nearest;
  d.lodMaxClamp = 32.0f;
  d.maxAnisotropy = 1;
  if (desc) {
    d.label = str(desc->label);
    d.addressModeU = em::to_em(desc->addressModeU);
    d.addressModeV = em::to_em(desc->addressModeV);
    d.addressModeW = em::to_em(desc->addressModeW);
    d.magFilter = em::to_em(desc->magFilter);
    d.minFilter = em::to_em(desc->minFilter);
    d.mipmapFilter = em::to_em(desc->mipmapFilter);
    d.lodMinClamp = desc->lodMinClamp;
    d.lodMaxClamp = desc->lodMaxClamp;
    d.compare = em::to_em(desc->compare);
    d.maxAnisotropy = desc->maxAnisotropy;
  }
  return h<WGPUSampler>(stipple_em_wgpuDeviceCreateSampler(EMH(Device, device), &d));
}

WGPUShaderModule DeviceCreateShaderModule(WGPUDevice device,
                                          const WGPUShaderModuleDescriptor* desc) {
  Strings str;
  em::WGPUShaderModuleDescriptor d{};
  d.label = str(desc->label);
  em::WGPUShaderModuleWGSLDescriptor wgsl{};
  for (const WGPUChainedStruct* c = desc->nextInChain; c; c = c->next) {
    if (c->sType == WGPUSType_ShaderSourceWGSL) {
      wgsl.chain.sType = em::WGPUSType_ShaderModuleWGSLDescriptor;
      wgsl.code = str(reinterpret_cast<const WGPUShaderSourceWGSL*>(c)->code);
      d.nextInChain = &wgsl.chain;
    }
  }
  return h<WGPUShaderModule>(stipple_em_wgpuDeviceCreateShaderModule(EMH(Device, device), &d));
}

WGPUBindGroupLayout DeviceCreateBindGroupLayout(WGPUDevice device,
                                                const WGPUBindGroupLayoutDescriptor* desc) {
  Strings str;
  std::vector<em::WGPUBindGroupLayoutEntry> entries(desc->entryCount);
  for (size_t i = 0; i < desc->entryCount; ++i) {
    const WGPUBindGroupLayoutEntry& s = desc->entries[i];
    em::WGPUBindGroupLayoutEntry& e = entries[i];
    e = {};
    e.binding = s.binding;
    e.visibility = flags(s.visibility);
    // The old header's "Undefined" (0) means "not this kind of binding", as BindingNotUsed does.
    if (s.buffer.type != WGPUBufferBindingType_BindingNotUsed &&
        s.buffer.type != WGPUBufferBindingType_Undefined) {
      e.buffer.type = em::to_em(s.buffer.type);
      e.buffer.hasDynamicOffset = s.buffer.hasDynamicOffset;
      e.buffer.minBindingSize = s.buffer.minBindingSize;
    }
    if (s.sampler.type != WGPUSamplerBindingType_BindingNotUsed &&
        s.sampler.type != WGPUSamplerBindingType_Undefined)
      e.sampler.type = em::to_em(s.sampler.type);
    if (s.texture.sampleType != WGPUTextureSampleType_BindingNotUsed &&
        s.texture.sampleType != WGPUTextureSampleType_Undefined) {
      e.texture.sampleType = em::to_em(s.texture.sampleType);
      e.texture.viewDimension = s.texture.viewDimension == WGPUTextureViewDimension_Undefined
                                    ? em::WGPUTextureViewDimension_2D
                                    : em::to_em(s.texture.viewDimension);
      e.texture.multisampled = s.texture.multisampled;
    }
    if (s.storageTexture.access != WGPUStorageTextureAccess_BindingNotUsed &&
        s.storageTexture.access != WGPUStorageTextureAccess_Undefined) {
      e.storageTexture.access = em::to_em(s.storageTexture.access);
      e.storageTexture.format = em::to_em(s.storageTexture.format);
      e.storageTexture.viewDimension =
          s.storageTexture.viewDimension == WGPUTextureViewDimension_Undefined
              ? em::WGPUTextureViewDimension_2D
              : em::to_em(s.storageTexture.viewDimension);
    }
  }
  em::WGPUBindGroupLayoutDescriptor d{};
  d.label = str(desc->label);
  d.entryCount = entries.size();
  d.entries = entries.data();
  return h<WGPUBindGroupLayout>(
      stipple_em_wgpuDeviceCreateBindGroupLayout(EMH(Device, device), &d));
}

WGPUBindGroup DeviceCreateBindGroup(WGPUDevice device, const WGPUBindGroupDescriptor* desc) {
  Strings str;
  std::vector<em::WGPUBindGroupEntry> entries(desc->entryCount);
  for (size_t i = 0; i < desc->entryCount; ++i) {
    const WGPUBindGroupEntry& s = desc->entries[i];
    entries[i] = {};
    entries[i].binding = s.binding;
    entries[i].buffer = EMH(Buffer, s.buffer);
    entries[i].offset = s.offset;
    entries[i].size = s.size;
    entries[i].sampler = EMH(Sampler, s.sampler);
    entries[i].textureView = EMH(TextureView, s.textureView);
  }
  em::WGPUBindGroupDescriptor d{};
  d.label = str(desc->label);
  d.layout = EMH(BindGroupLayout, desc->layout);
  d.entryCount = entries.size();
  d.entries = entries.data();
  return h<WGPUBindGroup>(stipple_em_wgpuDeviceCreateBindGroup(EMH(Device, device), &d));
}

WGPUPipelineLayout DeviceCreatePipelineLayout(WGPUDevice device,
                                              const WGPUPipelineLayoutDescriptor* desc) {
  Strings str;
  em::WGPUPipelineLayoutDescriptor d{};
  d.label = str(desc->label);
  d.bindGroupLayoutCount = desc->bindGroupLayoutCount;
  d.bindGroupLayouts = reinterpret_cast<const em::WGPUBindGroupLayout*>(desc->bindGroupLayouts);
  return h<WGPUPipelineLayout>(stipple_em_wgpuDeviceCreatePipelineLayout(EMH(Device, device), &d));
}

// Pipeline-overridable constants of one stage.
struct Constants {
  std::vector<em::WGPUConstantEntry> entries;
  Constants(Strings& str, size_t count, const WGPUConstantEntry* constants) {
    for (size_t i = 0; i < count; ++i) {
      em::WGPUConstantEntry e{};
      e.key = str(constants[i].key);
      e.value = constants[i].value;
      entries.push_back(e);
    }
  }
};

WGPUComputePipeline DeviceCreateComputePipeline(WGPUDevice device,
                                                const WGPUComputePipelineDescriptor* desc) {
  Strings str;
  Constants constants(str, desc->compute.constantCount, desc->compute.constants);
  em::WGPUComputePipelineDescriptor d{};
  d.label = str(desc->label);
  d.layout = EMH(PipelineLayout, desc->layout);
  d.compute.module = EMH(ShaderModule, desc->compute.module);
  d.compute.entryPoint = str(desc->compute.entryPoint);
  d.compute.constantCount = constants.entries.size();
  d.compute.constants = constants.entries.data();
  return h<WGPUComputePipeline>(
      stipple_em_wgpuDeviceCreateComputePipeline(EMH(Device, device), &d));
}

em::WGPUBlendComponent blend_component(const WGPUBlendComponent& c) {
  em::WGPUBlendComponent e{};
  e.operation = c.operation == WGPUBlendOperation_Undefined ? em::WGPUBlendOperation_Add
                                                            : em::to_em(c.operation);
  e.srcFactor =
      c.srcFactor == WGPUBlendFactor_Undefined ? em::WGPUBlendFactor_One : em::to_em(c.srcFactor);
  e.dstFactor =
      c.dstFactor == WGPUBlendFactor_Undefined ? em::WGPUBlendFactor_Zero : em::to_em(c.dstFactor);
  return e;
}

em::WGPUStencilFaceState stencil_face(const WGPUStencilFaceState& s) {
  auto op = [](WGPUStencilOperation o) {
    return o == WGPUStencilOperation_Undefined ? em::WGPUStencilOperation_Keep : em::to_em(o);
  };
  em::WGPUStencilFaceState e{};
  e.compare = s.compare == WGPUCompareFunction_Undefined ? em::WGPUCompareFunction_Always
                                                         : em::to_em(s.compare);
  e.failOp = op(s.failOp);
  e.depthFailOp = op(s.depthFailOp);
  e.passOp = op(s.passOp);
  return e;
}

WGPURenderPipeline DeviceCreateRenderPipeline(WGPUDevice device,
                                              const WGPURenderPipelineDescriptor* desc) {
  Strings str;
  em::WGPURenderPipelineDescriptor d{};
  d.label = str(desc->label);
  d.layout = EMH(PipelineLayout, desc->layout);

  const WGPUVertexState& vs = desc->vertex;
  Constants vertex_constants(str, vs.constantCount, vs.constants);
  std::vector<std::vector<em::WGPUVertexAttribute>> attributes(vs.bufferCount);
  std::vector<em::WGPUVertexBufferLayout> buffers(vs.bufferCount);
  for (size_t i = 0; i < vs.bufferCount; ++i) {
    const WGPUVertexBufferLayout& b = vs.buffers[i];
    for (size_t a = 0; a < b.attributeCount; ++a) {
      em::WGPUVertexAttribute e{};
      e.format = em::to_em(b.attributes[a].format);
      e.offset = b.attributes[a].offset;
      e.shaderLocation = b.attributes[a].shaderLocation;
      attributes[i].push_back(e);
    }
    buffers[i] = {};
    buffers[i].arrayStride = b.arrayStride;
    // A slot the pipeline does not use is VertexBufferNotUsed in the newer header.
    buffers[i].stepMode = b.stepMode == WGPUVertexStepMode_Instance
                              ? em::WGPUVertexStepMode_Instance
                          : b.attributeCount == 0 ? em::WGPUVertexStepMode_VertexBufferNotUsed
                                                  : em::WGPUVertexStepMode_Vertex;
    buffers[i].attributeCount = attributes[i].size();
    buffers[i].attributes = attributes[i].data();
  }
  d.vertex.module = EMH(ShaderModule, vs.module);
  d.vertex.entryPoint = str(vs.entryPoint);
  d.vertex.constantCount = vertex_constants.entries.size();
  d.vertex.constants = vertex_constants.entries.data();
  d.vertex.bufferCount = buffers.size();
  d.vertex.buffers = buffers.data();

  const WGPUPrimitiveState& p = desc->primitive;
  d.primitive.topology = p.topology == WGPUPrimitiveTopology_Undefined
                             ? em::WGPUPrimitiveTopology_TriangleList
                             : em::to_em(p.topology);
  d.primitive.stripIndexFormat = em::to_em(p.stripIndexFormat);
  d.primitive.frontFace =
      p.frontFace == WGPUFrontFace_Undefined ? em::WGPUFrontFace_CCW : em::to_em(p.frontFace);
  d.primitive.cullMode =
      p.cullMode == WGPUCullMode_Undefined ? em::WGPUCullMode_None : em::to_em(p.cullMode);
  em::WGPUPrimitiveDepthClipControl clip{};
  if (p.unclippedDepth) {
    clip.chain.sType = em::WGPUSType_PrimitiveDepthClipControl;
    clip.unclippedDepth = true;
    d.primitive.nextInChain = &clip.chain;
  }

  em::WGPUDepthStencilState depth{};
  if (desc->depthStencil) {
    const WGPUDepthStencilState& s = *desc->depthStencil;
    depth.format = em::to_em(s.format);
    depth.depthWriteEnabled = s.depthWriteEnabled == WGPUOptionalBool_True;
    depth.depthCompare = s.depthCompare == WGPUCompareFunction_Undefined
                             ? em::WGPUCompareFunction_Always
                             : em::to_em(s.depthCompare);
    depth.stencilFront = stencil_face(s.stencilFront);
    depth.stencilBack = stencil_face(s.stencilBack);
    depth.stencilReadMask = s.stencilReadMask;
    depth.stencilWriteMask = s.stencilWriteMask;
    depth.depthBias = s.depthBias;
    depth.depthBiasSlopeScale = s.depthBiasSlopeScale;
    depth.depthBiasClamp = s.depthBiasClamp;
    d.depthStencil = &depth;
  }
  d.multisample.count = desc->multisample.count ? desc->multisample.count : 1;
  d.multisample.mask = desc->multisample.mask;
  d.multisample.alphaToCoverageEnabled = desc->multisample.alphaToCoverageEnabled;

  em::WGPUFragmentState fragment{};
  std::vector<em::WGPUColorTargetState> targets;
  std::vector<em::WGPUBlendState> blends;
  std::optional<Constants> fragment_constants;
  if (desc->fragment) {
    const WGPUFragmentState& f = *desc->fragment;
    fragment_constants.emplace(str, f.constantCount, f.constants);
    blends.reserve(f.targetCount);
    for (size_t i = 0; i < f.targetCount; ++i) {
      const WGPUColorTargetState& t = f.targets[i];
      em::WGPUColorTargetState e{};
      e.format = em::to_em(t.format);
      e.writeMask = flags(t.writeMask);
      if (t.blend) {
        blends.push_back({blend_component(t.blend->color), blend_component(t.blend->alpha)});
        e.blend = &blends.back();
      }
      targets.push_back(e);
    }
    fragment.module = EMH(ShaderModule, f.module);
    fragment.entryPoint = str(f.entryPoint);
    fragment.constantCount = fragment_constants->entries.size();
    fragment.constants = fragment_constants->entries.data();
    fragment.targetCount = targets.size();
    fragment.targets = targets.data();
    d.fragment = &fragment;
  }
  return h<WGPURenderPipeline>(stipple_em_wgpuDeviceCreateRenderPipeline(EMH(Device, device), &d));
}

WGPUCommandEncoder DeviceCreateCommandEncoder(WGPUDevice device,
                                              const WGPUCommandEncoderDescriptor* desc) {
  Strings str;
  em::WGPUCommandEncoderDescriptor d{};
  if (desc) d.label = str(desc->label);
  return h<WGPUCommandEncoder>(stipple_em_wgpuDeviceCreateCommandEncoder(EMH(Device, device), &d));
}

WGPUQuerySet DeviceCreateQuerySet(WGPUDevice device, const WGPUQuerySetDescriptor* desc) {
  Strings str;
  em::WGPUQuerySetDescriptor d{};
  d.label = str(desc->label);
  d.type = em::to_em(desc->type);
  d.count = desc->count;
  return h<WGPUQuerySet>(stipple_em_wgpuDeviceCreateQuerySet(EMH(Device, device), &d));
}

void DevicePushErrorScope(WGPUDevice device, WGPUErrorFilter filter) {
  stipple_em_wgpuDevicePushErrorScope(EMH(Device, device), em::to_em(filter));
}

WGPUFuture DevicePopErrorScope(WGPUDevice device, WGPUPopErrorScopeCallbackInfo info) {
  stipple_em_wgpuDevicePopErrorScope(
      EMH(Device, device),
      [](em::WGPUErrorType type, const char* message, void* userdata) {
        auto* i = static_cast<WGPUPopErrorScopeCallbackInfo*>(userdata);
        i->callback(WGPUPopErrorScopeStatus_Success, em::from_em(type), view(message), i->userdata1,
                    i->userdata2);
        delete i;
      },
      keep(info));
  return WGPUFuture{0};
}

void DeviceRelease(WGPUDevice device) {
  stipple_em_wgpuDeviceRelease(EMH(Device, device));
}

// ---- queue ----------------------------------------------------------------------------------
void QueueSubmit(WGPUQueue queue, size_t count, const WGPUCommandBuffer* commands) {
  stipple_em_wgpuQueueSubmit(EMH(Queue, queue), count,
                             reinterpret_cast<const em::WGPUCommandBuffer*>(commands));
}

void QueueWriteBuffer(WGPUQueue queue, WGPUBuffer buffer, uint64_t offset, const void* data,
                      size_t size) {
  stipple_em_wgpuQueueWriteBuffer(EMH(Queue, queue), EMH(Buffer, buffer), offset, data, size);
}

em::WGPUImageCopyTexture copy_texture(const WGPUTexelCopyTextureInfo& t) {
  em::WGPUImageCopyTexture e{};
  e.texture = EMH(Texture, t.texture);
  e.mipLevel = t.mipLevel;
  e.origin = {t.origin.x, t.origin.y, t.origin.z};
  e.aspect =
      t.aspect == WGPUTextureAspect_Undefined ? em::WGPUTextureAspect_All : em::to_em(t.aspect);
  return e;
}

em::WGPUTextureDataLayout data_layout(const WGPUTexelCopyBufferLayout& l) {
  em::WGPUTextureDataLayout e{};
  e.offset = l.offset;
  e.bytesPerRow = l.bytesPerRow;
  e.rowsPerImage = l.rowsPerImage;
  return e;
}

void QueueWriteTexture(WGPUQueue queue, const WGPUTexelCopyTextureInfo* destination,
                       const void* data, size_t size, const WGPUTexelCopyBufferLayout* layout,
                       const WGPUExtent3D* extent) {
  em::WGPUImageCopyTexture dst = copy_texture(*destination);
  em::WGPUTextureDataLayout l = data_layout(*layout);
  em::WGPUExtent3D e{extent->width, extent->height, extent->depthOrArrayLayers};
  stipple_em_wgpuQueueWriteTexture(EMH(Queue, queue), &dst, data, size, &l, &e);
}

WGPUFuture QueueOnSubmittedWorkDone(WGPUQueue queue, WGPUQueueWorkDoneCallbackInfo info) {
  stipple_em_wgpuQueueOnSubmittedWorkDone(
      EMH(Queue, queue),
      [](em::WGPUQueueWorkDoneStatus status, void* userdata) {
        auto* i = static_cast<WGPUQueueWorkDoneCallbackInfo*>(userdata);
        i->callback(em::from_em(status), WGPUStringView{nullptr, 0}, i->userdata1, i->userdata2);
        delete i;
      },
      keep(info));
  return WGPUFuture{0};
}

float QueueGetTimestampPeriod(WGPUQueue) {
  return 1.0f;  // the browser's timestamps are nanoseconds
}

void QueueRelease(WGPUQueue queue) {
  stipple_em_wgpuQueueRelease(EMH(Queue, queue));
}

// ---- buffers, textures ----------------------------------------------------------------------
WGPUFuture BufferMapAsync(WGPUBuffer buffer, WGPUMapMode mode, size_t offset, size_t size,
                          WGPUBufferMapCallbackInfo info) {
  stipple_em_wgpuBufferMapAsync(
      EMH(Buffer, buffer), flags(mode), offset, size,
      [](em::WGPUBufferMapAsyncStatus status, void* userdata) {
        auto* i = static_cast<WGPUBufferMapCallbackInfo*>(userdata);
        bool ok = status == em::WGPUBufferMapAsyncStatus_Success;
        i->callback(ok ? WGPUMapAsyncStatus_Success : WGPUMapAsyncStatus_Error,
                    view(ok ? nullptr : "the browser could not map the buffer"), i->userdata1,
                    i->userdata2);
        delete i;
      },
      keep(info));
  return WGPUFuture{0};
}

// The browser hands out a mapped range once (a copy in wasm memory, written back at unmap; a
// second getMappedRange of an overlapping range fails), where webgpu.h implementations return
// the same memory again: the ranges given out are remembered until the buffer is unmapped.
struct MappedRange {
  size_t offset, size;
  void* data;
};
std::mutex g_mapped_mutex;
std::unordered_map<WGPUBuffer, std::vector<MappedRange>> g_mapped;

template <typename Get>
void* mapped_range(WGPUBuffer buffer, size_t offset, size_t size, Get get) {
  std::lock_guard lock(g_mapped_mutex);
  auto& ranges = g_mapped[buffer];
  for (const MappedRange& r : ranges)
    if (offset >= r.offset && (size == WGPU_WHOLE_MAP_SIZE ? r.size == WGPU_WHOLE_MAP_SIZE
                                                           : offset + size <= r.offset + r.size))
      return static_cast<uint8_t*>(r.data) + (offset - r.offset);
  void* data = get();
  if (data) ranges.push_back({offset, size, data});
  return data;
}

void forget_ranges(WGPUBuffer buffer) {
  std::lock_guard lock(g_mapped_mutex);
  g_mapped.erase(buffer);
}

void* BufferGetMappedRange(WGPUBuffer buffer, size_t offset, size_t size) {
  return mapped_range(buffer, offset, size, [&] {
    return stipple_em_wgpuBufferGetMappedRange(EMH(Buffer, buffer), offset, size);
  });
}
const void* BufferGetConstMappedRange(WGPUBuffer buffer, size_t offset, size_t size) {
  return mapped_range(buffer, offset, size, [&] {
    return const_cast<void*>(
        stipple_em_wgpuBufferGetConstMappedRange(EMH(Buffer, buffer), offset, size));
  });
}
void BufferUnmap(WGPUBuffer buffer) {
  forget_ranges(buffer);
  stipple_em_wgpuBufferUnmap(EMH(Buffer, buffer));
}
void BufferDestroy(WGPUBuffer buffer) {
  forget_ranges(buffer);
  stipple_em_wgpuBufferDestroy(EMH(Buffer, buffer));
}
void BufferRelease(WGPUBuffer buffer) {
  forget_ranges(buffer);
  stipple_em_wgpuBufferRelease(EMH(Buffer, buffer));
}
// The buffer's size from the browser's GPUBuffer (a double: library_webgpu.js's own
// wgpuBufferGetSize returns a Number where WASM_BIGINT wants a BigInt).
EM_JS(double, stipple_buffer_size, (em::WGPUBuffer buffer),
      { return WebGPU.mgrBuffer.get(buffer).size; });
uint64_t BufferGetSize(WGPUBuffer buffer) {
  return uint64_t(stipple_buffer_size(EMH(Buffer, buffer)));
}

WGPUTextureView TextureCreateView(WGPUTexture texture, const WGPUTextureViewDescriptor* desc) {
  if (!desc)
    return h<WGPUTextureView>(stipple_em_wgpuTextureCreateView(EMH(Texture, texture), nullptr));
  Strings str;
  em::WGPUTextureViewDescriptor d{};
  d.label = str(desc->label);
  d.format = em::to_em(desc->format);
  if (desc->format == WGPUTextureFormat_Undefined) d.format = em::WGPUTextureFormat_Undefined;
  d.dimension = desc->dimension == WGPUTextureViewDimension_Undefined
                    ? em::WGPUTextureViewDimension_Undefined
                    : em::to_em(desc->dimension);
  d.baseMipLevel = desc->baseMipLevel;
  d.mipLevelCount = desc->mipLevelCount;
  d.baseArrayLayer = desc->baseArrayLayer;
  d.arrayLayerCount = desc->arrayLayerCount;
  d.aspect = desc->aspect == WGPUTextureAspect_Undefined ? em::WGPUTextureAspect_All
                                                         : em::to_em(desc->aspect);
  return h<WGPUTextureView>(stipple_em_wgpuTextureCreateView(EMH(Texture, texture), &d));
}

void TextureRelease(WGPUTexture t) {
  stipple_em_wgpuTextureRelease(EMH(Texture, t));
}
void TextureViewRelease(WGPUTextureView v) {
  stipple_em_wgpuTextureViewRelease(EMH(TextureView, v));
}
void SamplerRelease(WGPUSampler s) {
  stipple_em_wgpuSamplerRelease(EMH(Sampler, s));
}
void ShaderModuleRelease(WGPUShaderModule m) {
  stipple_em_wgpuShaderModuleRelease(EMH(ShaderModule, m));
}
void BindGroupLayoutRelease(WGPUBindGroupLayout l) {
  stipple_em_wgpuBindGroupLayoutRelease(EMH(BindGroupLayout, l));
}
void BindGroupRelease(WGPUBindGroup g) {
  stipple_em_wgpuBindGroupRelease(EMH(BindGroup, g));
}
void PipelineLayoutRelease(WGPUPipelineLayout l) {
  stipple_em_wgpuPipelineLayoutRelease(EMH(PipelineLayout, l));
}
WGPUBindGroupLayout ComputePipelineGetBindGroupLayout(WGPUComputePipeline p, uint32_t group) {
  return h<WGPUBindGroupLayout>(
      stipple_em_wgpuComputePipelineGetBindGroupLayout(EMH(ComputePipeline, p), group));
}
void ComputePipelineRelease(WGPUComputePipeline p) {
  stipple_em_wgpuComputePipelineRelease(EMH(ComputePipeline, p));
}
WGPUBindGroupLayout RenderPipelineGetBindGroupLayout(WGPURenderPipeline p, uint32_t group) {
  return h<WGPUBindGroupLayout>(
      stipple_em_wgpuRenderPipelineGetBindGroupLayout(EMH(RenderPipeline, p), group));
}
void RenderPipelineRelease(WGPURenderPipeline p) {
  stipple_em_wgpuRenderPipelineRelease(EMH(RenderPipeline, p));
}
void QuerySetRelease(WGPUQuerySet q) {
  stipple_em_wgpuQuerySetRelease(EMH(QuerySet, q));
}

// ---- commands -------------------------------------------------------------------------------
WGPUComputePassEncoder CommandEncoderBeginComputePass(WGPUCommandEncoder encoder,
                                                      const WGPUComputePassDescriptor* desc) {
  Strings str;
  em::WGPUComputePassDescriptor d{};
  em::WGPUComputePassTimestampWrites writes{};
  if (desc) {
    d.label = str(desc->label);
    if (desc->timestampWrites) {
      writes.querySet = EMH(QuerySet, desc->timestampWrites->querySet);
      writes.beginningOfPassWriteIndex = desc->timestampWrites->beginningOfPassWriteIndex;
      writes.endOfPassWriteIndex = desc->timestampWrites->endOfPassWriteIndex;
      d.timestampWrites = &writes;
    }
  }
  return h<WGPUComputePassEncoder>(
      stipple_em_wgpuCommandEncoderBeginComputePass(EMH(CommandEncoder, encoder), &d));
}

WGPURenderPassEncoder CommandEncoderBeginRenderPass(WGPUCommandEncoder encoder,
                                                    const WGPURenderPassDescriptor* desc) {
  Strings str;
  em::WGPURenderPassDescriptor d{};
  d.label = str(desc->label);
  std::vector<em::WGPURenderPassColorAttachment> colors(desc->colorAttachmentCount);
  for (size_t i = 0; i < colors.size(); ++i) {
    const WGPURenderPassColorAttachment& c = desc->colorAttachments[i];
    colors[i] = {};
    colors[i].view = EMH(TextureView, c.view);
    colors[i].depthSlice = c.depthSlice;
    colors[i].resolveTarget = EMH(TextureView, c.resolveTarget);
    colors[i].loadOp = em::to_em(c.loadOp);
    colors[i].storeOp = em::to_em(c.storeOp);
    colors[i].clearValue = {c.clearValue.r, c.clearValue.g, c.clearValue.b, c.clearValue.a};
  }
  d.colorAttachmentCount = colors.size();
  d.colorAttachments = colors.data();
  em::WGPURenderPassDepthStencilAttachment depth{};
  if (desc->depthStencilAttachment) {
    const WGPURenderPassDepthStencilAttachment& s = *desc->depthStencilAttachment;
    depth.view = EMH(TextureView, s.view);
    depth.depthLoadOp = em::to_em(s.depthLoadOp);
    depth.depthStoreOp = em::to_em(s.depthStoreOp);
    if (s.depthLoadOp == WGPULoadOp_Undefined) depth.depthLoadOp = em::WGPULoadOp_Undefined;
    if (s.depthStoreOp == WGPUStoreOp_Undefined) depth.depthStoreOp = em::WGPUStoreOp_Undefined;
    // webgpu.h's "undefined" clear value is NaN, which browsers reject as a non-finite float
    // even where the value is unused (a read-only depth that is loaded, not cleared).
    depth.depthClearValue = std::isnan(s.depthClearValue) ? 0.0f : s.depthClearValue;
    depth.depthReadOnly = s.depthReadOnly;
    depth.stencilLoadOp = s.stencilLoadOp == WGPULoadOp_Undefined ? em::WGPULoadOp_Undefined
                                                                  : em::to_em(s.stencilLoadOp);
    depth.stencilStoreOp = s.stencilStoreOp == WGPUStoreOp_Undefined ? em::WGPUStoreOp_Undefined
                                                                     : em::to_em(s.stencilStoreOp);
    depth.stencilClearValue = s.stencilClearValue;
    depth.stencilReadOnly = s.stencilReadOnly;
    d.depthStencilAttachment = &depth;
  }
  d.occlusionQuerySet = EMH(QuerySet, desc->occlusionQuerySet);
  em::WGPURenderPassTimestampWrites writes{};
  if (desc->timestampWrites) {
    writes.querySet = EMH(QuerySet, desc->timestampWrites->querySet);
    writes.beginningOfPassWriteIndex = desc->timestampWrites->beginningOfPassWriteIndex;
    writes.endOfPassWriteIndex = desc->timestampWrites->endOfPassWriteIndex;
    d.timestampWrites = &writes;
  }
  return h<WGPURenderPassEncoder>(
      stipple_em_wgpuCommandEncoderBeginRenderPass(EMH(CommandEncoder, encoder), &d));
}

void CommandEncoderClearBuffer(WGPUCommandEncoder e, WGPUBuffer b, uint64_t offset, uint64_t size) {
  stipple_em_wgpuCommandEncoderClearBuffer(EMH(CommandEncoder, e), EMH(Buffer, b), offset, size);
}
void CommandEncoderCopyBufferToBuffer(WGPUCommandEncoder e, WGPUBuffer src, uint64_t src_offset,
                                      WGPUBuffer dst, uint64_t dst_offset, uint64_t size) {
  stipple_em_wgpuCommandEncoderCopyBufferToBuffer(EMH(CommandEncoder, e), EMH(Buffer, src),
                                                  src_offset, EMH(Buffer, dst), dst_offset, size);
}
void CommandEncoderCopyTextureToBuffer(WGPUCommandEncoder e, const WGPUTexelCopyTextureInfo* src,
                                       const WGPUTexelCopyBufferInfo* dst,
                                       const WGPUExtent3D* extent) {
  em::WGPUImageCopyTexture s = copy_texture(*src);
  em::WGPUImageCopyBuffer d{};
  d.layout = data_layout(dst->layout);
  d.buffer = EMH(Buffer, dst->buffer);
  em::WGPUExtent3D x{extent->width, extent->height, extent->depthOrArrayLayers};
  stipple_em_wgpuCommandEncoderCopyTextureToBuffer(EMH(CommandEncoder, e), &s, &d, &x);
}
void CommandEncoderResolveQuerySet(WGPUCommandEncoder e, WGPUQuerySet q, uint32_t first,
                                   uint32_t count, WGPUBuffer dst, uint64_t offset) {
  stipple_em_wgpuCommandEncoderResolveQuerySet(EMH(CommandEncoder, e), EMH(QuerySet, q), first,
                                               count, EMH(Buffer, dst), offset);
}
WGPUCommandBuffer CommandEncoderFinish(WGPUCommandEncoder e,
                                       const WGPUCommandBufferDescriptor* desc) {
  Strings str;
  em::WGPUCommandBufferDescriptor d{};
  if (desc) d.label = str(desc->label);
  return h<WGPUCommandBuffer>(stipple_em_wgpuCommandEncoderFinish(EMH(CommandEncoder, e), &d));
}
void CommandEncoderRelease(WGPUCommandEncoder e) {
  stipple_em_wgpuCommandEncoderRelease(EMH(CommandEncoder, e));
}
void CommandBufferRelease(WGPUCommandBuffer b) {
  stipple_em_wgpuCommandBufferRelease(EMH(CommandBuffer, b));
}

void ComputePassEncoderSetPipeline(WGPUComputePassEncoder p, WGPUComputePipeline pipeline) {
  stipple_em_wgpuComputePassEncoderSetPipeline(EMH(ComputePassEncoder, p),
                                               EMH(ComputePipeline, pipeline));
}
void ComputePassEncoderSetBindGroup(WGPUComputePassEncoder p, uint32_t index, WGPUBindGroup g,
                                    size_t count, const uint32_t* offsets) {
  stipple_em_wgpuComputePassEncoderSetBindGroup(EMH(ComputePassEncoder, p), index,
                                                EMH(BindGroup, g), count, offsets);
}
void ComputePassEncoderDispatchWorkgroups(WGPUComputePassEncoder p, uint32_t x, uint32_t y,
                                          uint32_t z) {
  stipple_em_wgpuComputePassEncoderDispatchWorkgroups(EMH(ComputePassEncoder, p), x, y, z);
}
void ComputePassEncoderDispatchWorkgroupsIndirect(WGPUComputePassEncoder p, WGPUBuffer buffer,
                                                  uint64_t offset) {
  stipple_em_wgpuComputePassEncoderDispatchWorkgroupsIndirect(EMH(ComputePassEncoder, p),
                                                              EMH(Buffer, buffer), offset);
}
void ComputePassEncoderEnd(WGPUComputePassEncoder p) {
  stipple_em_wgpuComputePassEncoderEnd(EMH(ComputePassEncoder, p));
}
void ComputePassEncoderRelease(WGPUComputePassEncoder p) {
  stipple_em_wgpuComputePassEncoderRelease(EMH(ComputePassEncoder, p));
}

void RenderPassEncoderSetPipeline(WGPURenderPassEncoder p, WGPURenderPipeline pipeline) {
  stipple_em_wgpuRenderPassEncoderSetPipeline(EMH(RenderPassEncoder, p),
                                              EMH(RenderPipeline, pipeline));
}
void RenderPassEncoderSetBindGroup(WGPURenderPassEncoder p, uint32_t index, WGPUBindGroup g,
                                   size_t count, const uint32_t* offsets) {
  stipple_em_wgpuRenderPassEncoderSetBindGroup(EMH(RenderPassEncoder, p), index, EMH(BindGroup, g),
                                               count, offsets);
}
void RenderPassEncoderSetVertexBuffer(WGPURenderPassEncoder p, uint32_t slot, WGPUBuffer b,
                                      uint64_t offset, uint64_t size) {
  stipple_em_wgpuRenderPassEncoderSetVertexBuffer(EMH(RenderPassEncoder, p), slot, EMH(Buffer, b),
                                                  offset, size);
}
void RenderPassEncoderSetIndexBuffer(WGPURenderPassEncoder p, WGPUBuffer b, WGPUIndexFormat f,
                                     uint64_t offset, uint64_t size) {
  stipple_em_wgpuRenderPassEncoderSetIndexBuffer(EMH(RenderPassEncoder, p), EMH(Buffer, b),
                                                 em::to_em(f), offset, size);
}
void RenderPassEncoderSetScissorRect(WGPURenderPassEncoder p, uint32_t x, uint32_t y, uint32_t w,
                                     uint32_t h_) {
  stipple_em_wgpuRenderPassEncoderSetScissorRect(EMH(RenderPassEncoder, p), x, y, w, h_);
}
void RenderPassEncoderDraw(WGPURenderPassEncoder p, uint32_t vertices, uint32_t instances,
                           uint32_t first_vertex, uint32_t first_instance) {
  stipple_em_wgpuRenderPassEncoderDraw(EMH(RenderPassEncoder, p), vertices, instances, first_vertex,
                                       first_instance);
}
void RenderPassEncoderDrawIndexed(WGPURenderPassEncoder p, uint32_t indices, uint32_t instances,
                                  uint32_t first_index, int32_t base_vertex,
                                  uint32_t first_instance) {
  stipple_em_wgpuRenderPassEncoderDrawIndexed(EMH(RenderPassEncoder, p), indices, instances,
                                              first_index, base_vertex, first_instance);
}
void RenderPassEncoderDrawIndirect(WGPURenderPassEncoder p, WGPUBuffer b, uint64_t offset) {
  stipple_em_wgpuRenderPassEncoderDrawIndirect(EMH(RenderPassEncoder, p), EMH(Buffer, b), offset);
}
void RenderPassEncoderEnd(WGPURenderPassEncoder p) {
  stipple_em_wgpuRenderPassEncoderEnd(EMH(RenderPassEncoder, p));
}
void RenderPassEncoderRelease(WGPURenderPassEncoder p) {
  stipple_em_wgpuRenderPassEncoderRelease(EMH(RenderPassEncoder, p));
}

// ---- surfaces (a canvas) --------------------------------------------------------------------
WGPUSurface InstanceCreateSurface(WGPUInstance instance, const WGPUSurfaceDescriptor* desc) {
  Strings str;
  em::WGPUSurfaceDescriptor d{};
  d.label = str(desc->label);
  em::WGPUSurfaceDescriptorFromCanvasHTMLSelector canvas{};
  for (const WGPUChainedStruct* c = desc->nextInChain; c; c = c->next) {
    if (c->sType == kSurfaceSourceCanvasSelector) {
      canvas.chain.sType = em::WGPUSType_SurfaceDescriptorFromCanvasHTMLSelector;
      canvas.selector = reinterpret_cast<const SurfaceSourceCanvasSelector*>(c)->selector;
      d.nextInChain = &canvas.chain;
    }
  }
  if (!d.nextInChain) return nullptr;  // only canvases exist in a page
  return h<WGPUSurface>(stipple_em_wgpuInstanceCreateSurface(EMH(Instance, instance), &d));
}

void SurfaceConfigure(WGPUSurface surface, const WGPUSurfaceConfiguration* config) {
  em::WGPUSurfaceConfiguration c{};
  c.device = EMH(Device, config->device);
  c.format = em::to_em(config->format);
  c.usage = flags(config->usage);
  std::vector<em::WGPUTextureFormat> formats;
  for (size_t i = 0; i < config->viewFormatCount; ++i)
    formats.push_back(em::to_em(config->viewFormats[i]));
  c.viewFormatCount = formats.size();
  c.viewFormats = formats.data();
  c.alphaMode = config->alphaMode == WGPUCompositeAlphaMode_Auto ? em::WGPUCompositeAlphaMode_Opaque
                                                                 : em::to_em(config->alphaMode);
  c.width = config->width;
  c.height = config->height;
  c.presentMode = em::WGPUPresentMode_Fifo;
  stipple_em_wgpuSurfaceConfigure(EMH(Surface, surface), &c);
}

void SurfaceUnconfigure(WGPUSurface surface) {
  stipple_em_wgpuSurfaceUnconfigure(EMH(Surface, surface));
}

WGPUStatus SurfaceGetCapabilities(WGPUSurface surface, WGPUAdapter adapter,
                                  WGPUSurfaceCapabilities* caps) {
  // The canvas's preferred format first, then the other 8-bit one.
  const WGPUTextureFormat preferred = em::from_em(
      stipple_em_wgpuSurfaceGetPreferredFormat(EMH(Surface, surface), EMH(Adapter, adapter)));
  auto* formats = static_cast<WGPUTextureFormat*>(std::malloc(sizeof(WGPUTextureFormat) * 2));
  formats[0] = preferred;
  formats[1] = preferred == WGPUTextureFormat_BGRA8Unorm ? WGPUTextureFormat_RGBA8Unorm
                                                         : WGPUTextureFormat_BGRA8Unorm;
  auto* present = static_cast<WGPUPresentMode*>(std::malloc(sizeof(WGPUPresentMode)));
  present[0] = WGPUPresentMode_Fifo;
  auto* alpha =
      static_cast<WGPUCompositeAlphaMode*>(std::malloc(sizeof(WGPUCompositeAlphaMode) * 2));
  alpha[0] = WGPUCompositeAlphaMode_Opaque;
  alpha[1] = WGPUCompositeAlphaMode_Premultiplied;
  WGPUChainedStruct* next = caps->nextInChain;
  *caps = WGPUSurfaceCapabilities{};
  caps->nextInChain = next;
  caps->usages = WGPUTextureUsage_RenderAttachment | WGPUTextureUsage_CopySrc |
                 WGPUTextureUsage_CopyDst | WGPUTextureUsage_TextureBinding;
  caps->formatCount = 2;
  caps->formats = formats;
  caps->presentModeCount = 1;
  caps->presentModes = present;
  caps->alphaModeCount = 2;
  caps->alphaModes = alpha;
  return WGPUStatus_Success;
}

void SurfaceCapabilitiesFreeMembers(WGPUSurfaceCapabilities caps) {
  std::free(const_cast<WGPUTextureFormat*>(caps.formats));
  std::free(const_cast<WGPUPresentMode*>(caps.presentModes));
  std::free(const_cast<WGPUCompositeAlphaMode*>(caps.alphaModes));
}

void SurfaceGetCurrentTexture(WGPUSurface surface, WGPUSurfaceTexture* texture) {
  em::WGPUSurfaceTexture e{};
  stipple_em_wgpuSurfaceGetCurrentTexture(EMH(Surface, surface), &e);
  texture->texture = h<WGPUTexture>(e.texture);
  texture->status = e.texture ? WGPUSurfaceGetCurrentTextureStatus_SuccessOptimal
                              : WGPUSurfaceGetCurrentTextureStatus_Error;
}

WGPUStatus SurfacePresent(WGPUSurface) {
  return WGPUStatus_Success;  // the browser presents when control returns to it
}

void SurfaceRelease(WGPUSurface surface) {
  stipple_em_wgpuSurfaceRelease(EMH(Surface, surface));
}

struct Entry {
  const char* name;
  void* proc;
};
#define STIPPLE_ENTRY(name) {"wgpu" #name, reinterpret_cast<void*>(&name)},
const Entry kEntries[] =
    {STIPPLE_ENTRY(CreateInstance) STIPPLE_ENTRY(InstanceProcessEvents) STIPPLE_ENTRY(
        InstanceRequestAdapter) STIPPLE_ENTRY(InstanceCreateSurface) STIPPLE_ENTRY(InstanceRelease)
         STIPPLE_ENTRY(AdapterGetInfo) STIPPLE_ENTRY(AdapterInfoFreeMembers) STIPPLE_ENTRY(
             AdapterGetLimits) STIPPLE_ENTRY(AdapterGetFeatures)
             STIPPLE_ENTRY(SupportedFeaturesFreeMembers) STIPPLE_ENTRY(
                 AdapterRequestDevice) STIPPLE_ENTRY(AdapterRelease) STIPPLE_ENTRY(DeviceGetLimits)
                 STIPPLE_ENTRY(DeviceGetQueue) STIPPLE_ENTRY(DeviceCreateBuffer) STIPPLE_ENTRY(
                     DeviceCreateTexture) STIPPLE_ENTRY(DeviceCreateSampler)
                     STIPPLE_ENTRY(DeviceCreateShaderModule) STIPPLE_ENTRY(
                         DeviceCreateBindGroupLayout) STIPPLE_ENTRY(DeviceCreateBindGroup)
                         STIPPLE_ENTRY(DeviceCreatePipelineLayout) STIPPLE_ENTRY(
                             DeviceCreateComputePipeline) STIPPLE_ENTRY(DeviceCreateRenderPipeline)
                             STIPPLE_ENTRY(DeviceCreateCommandEncoder) STIPPLE_ENTRY(
                                 DeviceCreateQuerySet) STIPPLE_ENTRY(DevicePushErrorScope)
                                 STIPPLE_ENTRY(DevicePopErrorScope) STIPPLE_ENTRY(
                                     DeviceRelease) STIPPLE_ENTRY(QueueSubmit)
                                     STIPPLE_ENTRY(QueueWriteBuffer) STIPPLE_ENTRY(
                                         QueueWriteTexture) STIPPLE_ENTRY(QueueOnSubmittedWorkDone)
                                         STIPPLE_ENTRY(QueueGetTimestampPeriod) STIPPLE_ENTRY(
                                             QueueRelease) STIPPLE_ENTRY(BufferMapAsync)
                                             STIPPLE_ENTRY(BufferGetMappedRange) STIPPLE_ENTRY(
                                                 BufferGetConstMappedRange) STIPPLE_ENTRY(BufferUnmap)
                                                 STIPPLE_ENTRY(BufferDestroy) STIPPLE_ENTRY(
                                                     BufferGetSize) STIPPLE_ENTRY(BufferRelease)
                                                     STIPPLE_ENTRY(TextureCreateView) STIPPLE_ENTRY(
                                                         TextureRelease) STIPPLE_ENTRY(TextureViewRelease)
                                                         STIPPLE_ENTRY(SamplerRelease) STIPPLE_ENTRY(ShaderModuleRelease) STIPPLE_ENTRY(
                                                             BindGroupLayoutRelease) STIPPLE_ENTRY(BindGroupRelease)
                                                             STIPPLE_ENTRY(PipelineLayoutRelease) STIPPLE_ENTRY(
                                                                 ComputePipelineGetBindGroupLayout) STIPPLE_ENTRY(ComputePipelineRelease) STIPPLE_ENTRY(RenderPipelineGetBindGroupLayout) STIPPLE_ENTRY(RenderPipelineRelease) STIPPLE_ENTRY(QuerySetRelease) STIPPLE_ENTRY(CommandEncoderBeginComputePass) STIPPLE_ENTRY(CommandEncoderBeginRenderPass) STIPPLE_ENTRY(CommandEncoderClearBuffer) STIPPLE_ENTRY(CommandEncoderCopyBufferToBuffer) STIPPLE_ENTRY(CommandEncoderCopyTextureToBuffer) STIPPLE_ENTRY(CommandEncoderResolveQuerySet) STIPPLE_ENTRY(CommandEncoderFinish) STIPPLE_ENTRY(CommandEncoderRelease) STIPPLE_ENTRY(CommandBufferRelease) STIPPLE_ENTRY(ComputePassEncoderSetPipeline) STIPPLE_ENTRY(ComputePassEncoderSetBindGroup) STIPPLE_ENTRY(ComputePassEncoderDispatchWorkgroups)
                                                                 STIPPLE_ENTRY(
                                                                     ComputePassEncoderDispatchWorkgroupsIndirect) STIPPLE_ENTRY(ComputePassEncoderEnd)
                                                                     STIPPLE_ENTRY(
                                                                         ComputePassEncoderRelease) STIPPLE_ENTRY(RenderPassEncoderSetPipeline)
                                                                         STIPPLE_ENTRY(
                                                                             RenderPassEncoderSetBindGroup) STIPPLE_ENTRY(RenderPassEncoderSetVertexBuffer)
                                                                             STIPPLE_ENTRY(
                                                                                 RenderPassEncoderSetIndexBuffer) STIPPLE_ENTRY(RenderPassEncoderSetScissorRect)
                                                                                 STIPPLE_ENTRY(
                                                                                     RenderPassEncoderDraw) STIPPLE_ENTRY(RenderPassEncoderDrawIndexed)
                                                                                     STIPPLE_ENTRY(
                                                                                         RenderPassEncoderDrawIndirect)
                                                                                         STIPPLE_ENTRY(
                                                                                             RenderPassEncoderEnd) STIPPLE_ENTRY(RenderPassEncoderRelease)
                                                                                             STIPPLE_ENTRY(
                                                                                                 SurfaceConfigure)
                                                                                                 STIPPLE_ENTRY(SurfaceUnconfigure) STIPPLE_ENTRY(
                                                                                                     SurfaceGetCapabilities)
                                                                                                     STIPPLE_ENTRY(
                                                                                                         SurfaceCapabilitiesFreeMembers)
                                                                                                         STIPPLE_ENTRY(
                                                                                                             SurfaceGetCurrentTexture)
                                                                                                             STIPPLE_ENTRY(
                                                                                                                 SurfacePresent)
                                                                                                                 STIPPLE_ENTRY(
                                                                                                                     SurfaceRelease)};
#undef STIPPLE_ENTRY

}  // namespace

void* lookup(const char* name) {
  for (const Entry& e : kEntries)
    if (std::strcmp(e.name, name) == 0) return e.proc;
  return nullptr;
}

}  // namespace stipple::gpu::web
