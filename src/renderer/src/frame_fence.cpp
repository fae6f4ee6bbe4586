#include "stipple/renderer/frame_fence.hpp"

#include "stipple/renderer/gpu.hpp"

namespace stipple::gpu {

uint64_t FrameFence::mark(Context& ctx) {
  const uint64_t serial = ++submitted_;
  WGPUQueueWorkDoneCallbackInfo info = WGPU_QUEUE_WORK_DONE_CALLBACK_INFO_INIT;
  info.mode = WGPUCallbackMode_AllowProcessEvents;
  info.callback = [](WGPUQueueWorkDoneStatus status, WGPUStringView, void* state, void* serial) {
    auto* s = static_cast<std::shared_ptr<State>*>(state);
    if (status == WGPUQueueWorkDoneStatus_Success) {
      const uint64_t n = uint64_t(reinterpret_cast<uintptr_t>(serial));
      uint64_t seen = (*s)->completed.load(std::memory_order_relaxed);
      while (seen < n && !(*s)->completed.compare_exchange_weak(seen, n, std::memory_order_release))
        ;
    }
    delete s;
  };
  info.userdata1 = new std::shared_ptr<State>(state_);
  info.userdata2 = reinterpret_cast<void*>(uintptr_t(serial));
  wgpuQueueOnSubmittedWorkDone(ctx.queue.get(), info);
  return serial;
}

}  // namespace stipple::gpu
