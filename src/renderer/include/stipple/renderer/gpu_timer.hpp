#pragma once
// GPU time per pass from timestamp queries (where the adapter has the feature): each pass gets
// a begin/end pair; results are resolved into a buffer and read back in milliseconds, either
// right away (read_pass_times: the caller waits for the frame) or a few frames later without
// waiting (PassTimerRing: each frame in flight has a timer of its own, read back through a
// mapAsync that a later frame finds completed). Waiting for each frame costs a round trip to the
// GPU per frame: in a browser, through its GPU process.
#include <cstdint>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include "stipple/renderer/gpu.hpp"

namespace stipple::gpu {

struct PassTimer {
  bool enabled = false;
  uint32_t capacity = 0;  // passes
  QuerySet queries;
  Buffer resolved;
  // A ring's timer: MapRead, the resolved times are copied into it with the frame's commands.
  Buffer readback;
};

PassTimer create_pass_timer(Context& ctx, uint32_t passes);
// Timestamp writes for pass `index`, or null when timing is off (pass it to the descriptor).
const WGPUPassTimestampWrites* pass_timestamps(PassTimer& timer, uint32_t index,
                                               WGPUPassTimestampWrites& storage);
// Records the resolve of the first `passes` passes' queries (all by default) into the timer's
// buffer (end of the frame's encoder), and for a ring's timer the copy into its readback buffer.
void resolve_pass_timer(PassTimer& timer, WGPUCommandEncoder encoder, uint32_t passes = UINT32_MAX);
// Blocks until the frame is done; milliseconds per pass (empty when timing is off).
std::vector<double> read_pass_times(Context& ctx, PassTimer& timer);

// Timers for frames in flight, read back without waiting. A frame takes a free slot's timer
// (acquire_pass_timer), records its passes with it, and once submitted hands the slot the names
// of the passes it timed (pass_timer_submitted), which maps the slot's readback buffer
// asynchronously; collect_pass_times later takes the frames whose maps completed, each with its
// own pass names (a frame's passes can differ from the next one's). A slot is free again once
// its results are taken, so its queries are never overwritten before they are read.
struct PassTimerSlotState;  // map state, shared with the map callback
struct PassTimerRing {
  struct Slot {
    PassTimer timer;
    std::shared_ptr<PassTimerSlotState> state;
    uint64_t frame = 0;
    std::vector<std::string> names;  // per query pair: the pass it timed ("": none)
  };
  std::vector<Slot> slots;
};

// `slots` timers of `passes` passes each; none where the adapter has no timestamp queries.
PassTimerRing create_pass_timer_ring(Context& ctx, uint32_t passes, uint32_t slots);
// A free slot's timer for the next frame, or null: no timing, or every slot's results are still
// on their way (the frame goes untimed rather than waiting).
PassTimer* acquire_pass_timer(PassTimerRing& ring);
// After the frame that used `timer` (from acquire_pass_timer) was submitted: `names[i]` is the
// pass that wrote query pair i ("" where none did). The slot's results are mapped without
// waiting; a frame that timed no pass leaves the slot free and has no times.
void pass_timer_submitted(PassTimerRing& ring, PassTimer* timer, uint64_t frame,
                          std::vector<std::string> names);

// One frame's GPU milliseconds per pass.
struct FrameTimes {
  uint64_t frame = 0;
  std::map<std::string, double> pass_ms;
};
// The frames whose results arrived, oldest first, stopping at the oldest one still on its way
// (so that times are taken in frame order); their slots are free again. Without `wait` nothing
// blocks: natively the implementation's events are processed once (wgpuDevicePoll,
// wgpuInstanceProcessEvents); in the browser not even that, since its event loop delivers the map
// callbacks whenever the page yields (processing events there would yield the thread). With
// `wait`, every frame in flight is waited for.
std::vector<FrameTimes> collect_pass_times(Context& ctx, PassTimerRing& ring, bool wait);
// Frames whose results are still on their way.
uint32_t pass_times_in_flight(const PassTimerRing& ring);

}  // namespace stipple::gpu
