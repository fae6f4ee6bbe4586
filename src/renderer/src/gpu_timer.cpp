#include "stipple/renderer/gpu_timer.hpp"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <utility>

#include "stipple/core/error.hpp"
#include "stipple/renderer/staging.hpp"
#include "webgpu_loader.hpp"

namespace stipple::gpu {

// Written by the map callback (under the context's event processing, or the browser's event
// loop), read by collect_pass_times.
struct PassTimerSlotState {
  enum class Phase { Free, Mapping, Mapped, Failed };
  Phase phase = Phase::Free;
  std::string message;
};

namespace {

using Phase = PassTimerSlotState::Phase;

// Resolved timestamps (begin/end pairs) to milliseconds per pass.
std::vector<double> ticks_to_ms(Context& ctx, const uint64_t* ticks, uint32_t passes) {
  // WebGPU resolves to nanoseconds; wgpu-native resolves raw ticks and reports their period.
  double period_ns = 1.0;
  if (has_proc("wgpuQueueGetTimestampPeriod"))
    period_ns = wgpuQueueGetTimestampPeriod(ctx.queue.get());
  std::vector<double> ms(passes);
  for (uint32_t i = 0; i < passes; ++i) {
    uint64_t begin = ticks[i * 2], end = ticks[i * 2 + 1];
    ms[i] = end >= begin ? double(end - begin) * period_ns * 1e-6 : 0.0;
  }
  return ms;
}

uint64_t timer_bytes(const PassTimer& timer) {
  return uint64_t(timer.capacity) * 2 * 8;
}

}  // namespace

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
      create_buffer(ctx, timer_bytes(timer), WGPUBufferUsage_QueryResolve | WGPUBufferUsage_CopySrc,
                    "pass-timestamps");
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
  if (timer.readback)
    wgpuCommandEncoderCopyBufferToBuffer(encoder, timer.resolved.get(), 0, timer.readback.get(), 0,
                                         uint64_t(count) * 16);
}

std::vector<double> read_pass_times(Context& ctx, PassTimer& timer) {
  if (!timer.enabled) return {};
  auto bytes = read_buffer(ctx, timer.resolved.get(), 0, timer_bytes(timer));
  std::vector<uint64_t> ticks(timer.capacity * 2);
  std::memcpy(ticks.data(), bytes.data(), ticks.size() * 8);
  return ticks_to_ms(ctx, ticks.data(), timer.capacity);
}

PassTimerRing create_pass_timer_ring(Context& ctx, uint32_t passes, uint32_t slots) {
  PassTimerRing ring;
  for (uint32_t i = 0; i < slots; ++i) {
    PassTimerRing::Slot slot;
    slot.timer = create_pass_timer(ctx, passes);
    if (!slot.timer.enabled) return {};
    slot.timer.readback = create_buffer(ctx, timer_bytes(slot.timer),
                                        WGPUBufferUsage_MapRead | WGPUBufferUsage_CopyDst,
                                        "pass-timestamps-readback");
    slot.state = std::make_shared<PassTimerSlotState>();
    ring.slots.push_back(std::move(slot));
  }
  return ring;
}

PassTimer* acquire_pass_timer(PassTimerRing& ring) {
  for (auto& slot : ring.slots)
    if (slot.state->phase == Phase::Free) return &slot.timer;
  return nullptr;
}

void pass_timer_submitted(PassTimerRing& ring, PassTimer* timer, uint64_t frame,
                          std::vector<std::string> names) {
  auto slot = std::find_if(ring.slots.begin(), ring.slots.end(),
                           [timer](const PassTimerRing::Slot& s) { return &s.timer == timer; });
  if (slot == ring.slots.end()) fail("pass_timer_submitted: the timer is not the ring's");
  if (slot->state->phase != Phase::Free) fail("pass_timer_submitted: the timer is in use");
  if (std::all_of(names.begin(), names.end(), [](const std::string& n) { return n.empty(); }))
    return;  // nothing was resolved: nothing to read
  names.resize(timer->capacity);
  slot->frame = frame;
  slot->names = std::move(names);
  map_async(timer->readback.get(), WGPUMapMode_Read, timer_bytes(*timer), slot->state);
}

uint32_t pass_times_in_flight(const PassTimerRing& ring) {
  return uint32_t(std::count_if(ring.slots.begin(), ring.slots.end(),
                                [](const auto& slot) { return slot.state->phase != Phase::Free; }));
}

std::vector<FrameTimes> collect_pass_times(Context& ctx, PassTimerRing& ring, bool wait) {
  std::vector<FrameTimes> arrived;
  if (pass_times_in_flight(ring) == 0) return arrived;
  auto mapping = [&ring] {
    return std::any_of(ring.slots.begin(), ring.slots.end(),
                       [](const auto& slot) { return slot.state->phase == Phase::Mapping; });
  };
  // (Uncaptured errors are left to the frame's own check, which names what it was doing.)
  settle_maps(ctx, wait, mapping, "pass times");
  // Oldest first; a frame still mapping stops the walk (a later one's times wait for it).
  std::vector<PassTimerRing::Slot*> order;
  for (auto& slot : ring.slots)
    if (slot.state->phase != Phase::Free) order.push_back(&slot);
  std::sort(order.begin(), order.end(), [](auto* a, auto* b) { return a->frame < b->frame; });
  for (PassTimerRing::Slot* slot : order) {
    PassTimerSlotState& state = *slot->state;
    if (state.phase == Phase::Mapping) break;
    if (state.phase == Phase::Failed)
      fail("reading pass times back failed (frame {}): {}", slot->frame, state.message);
    const PassTimer& timer = slot->timer;
    const void* mapped = wgpuBufferGetConstMappedRange(timer.readback.get(), 0, timer_bytes(timer));
    if (!mapped) fail("reading pass times back: the mapped range is null");
    std::vector<uint64_t> ticks(timer.capacity * 2);
    std::memcpy(ticks.data(), mapped, ticks.size() * 8);
    wgpuBufferUnmap(timer.readback.get());
    state.phase = Phase::Free;
    const std::vector<double> ms = ticks_to_ms(ctx, ticks.data(), timer.capacity);
    FrameTimes times{slot->frame, {}};
    for (uint32_t i = 0; i < timer.capacity; ++i)
      if (!slot->names[i].empty()) times.pass_ms[slot->names[i]] = ms[i];
    arrived.push_back(std::move(times));
  }
  return arrived;
}

}  // namespace stipple::gpu
