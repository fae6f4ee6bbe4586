#pragma once
// Which submitted frames the GPU has finished. After a frame's last submit, mark() asks the queue
// to report when everything submitted so far is done; completed() is the newest frame serial
// reported (the callbacks run inside Context::poll). A queue finishes work in submission order,
// so every serial up to completed() is done too. Resources that a frame in flight may still read
// (suballocated ranges, say) wait for their serial before they are reused.
#include <atomic>
#include <cstdint>
#include <memory>

namespace stipple::gpu {

struct Context;

class FrameFence {
 public:
  // Returns the serial of the frame just submitted (1, 2, ...).
  uint64_t mark(Context& ctx);
  uint64_t submitted() const { return submitted_; }
  uint64_t completed() const { return state_->completed.load(std::memory_order_acquire); }

 private:
  // Shared with the pending callbacks, which may outlive the fence (they fire, cancelled, when
  // the device goes away).
  struct State {
    std::atomic<uint64_t> completed{0};
  };
  std::shared_ptr<State> state_ = std::make_shared<State>();
  uint64_t submitted_ = 0;
};

}  // namespace stipple::gpu
