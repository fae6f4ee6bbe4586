#include "stipple/renderer/gpu_timer.hpp"

#include <algorithm>
#include <cstring>

#include "webgpu_loader.hpp"

namespace stipple::gpu {

PassTimer create_pass_timer(Context& ctx, uint32_t passes) {
  PassTimer timer;
  if (!ctx.has_feature(WGPUFeatureName_TimestampQuery) || passes == 0) return timer;
  timer.enabled = true;
  timer.capacity = passes;
  WGPUQuerySetDescriptor desc = WGPU_QUERY_SET_DESCRIPTOR_INIT;
  desc.label = to_view("pass-timestamps");
  desc.type = WGPUQueryType_Timestamp;
  desc.count = passes * 2;
  timer.queries = QuerySet(wgpuDeviceCreateQuerySet(ctx.device.get(), &desc));
  timer.resolved =
      create_buffer(ctx, uint64_t(passes) * 2 * 8,
                    WGPUBufferUsage_QueryResolve | WGPUBufferUsage_CopySrc, "pass-timestamps");
  return timer;
}

const WGPUPassTimestampWrites* pass_timestamps(PassTimer& timer, uint32_t index,
                                               WGPUPassTimestampWrites& storage) {
  if (!timer.enabled || index >= timer.capacity) return nullptr;
  storage = WGPU_PASS_TIMESTAMP_WRITES_INIT;
  storage.querySet = timer.queries.get();
  storage.beginningOfPassWriteIndex = index * 2;
  storage.endOfPassWriteIndex = index * 2 + 1;
  return &storage;
}

void resolve_pass_timer(PassTimer& timer, WGPUCommandEncoder encoder, uint32_t passes) {
  if (!timer.enabled) return;
  uint32_t count = std::min(passes, timer.capacity);
  if (count == 0) return;
  wgpuCommandEncoderResolveQuerySet(encoder, timer.queries.get(), 0, count * 2,
                                    timer.resolved.get(), 0);
}

std::vector<double> read_pass_times(Context& ctx, PassTimer& timer) {
  if (!timer.enabled) return {};
  auto bytes = read_buffer(ctx, timer.resolved.get(), 0, uint64_t(timer.capacity) * 16);
  std::vector<uint64_t> ticks(timer.capacity * 2);
  std::memcpy(ticks.data(), bytes.data(), ticks.size() * 8);
  // WebGPU resolves to nanoseconds; wgpu-native resolves raw ticks and reports their period.
  double period_ns = 1.0;
  if (has_proc("wgpuQueueGetTimestampPeriod"))
    period_ns = wgpuQueueGetTimestampPeriod(ctx.queue.get());
  std::vector<double> ms(timer.capacity);
  for (uint32_t i = 0; i < timer.capacity; ++i) {
    uint64_t begin = ticks[i * 2], end = ticks[i * 2 + 1];
    ms[i] = end >= begin ? double(end - begin) * period_ns * 1e-6 : 0.0;
  }
  return ms;
}

}  // namespace stipple::gpu
