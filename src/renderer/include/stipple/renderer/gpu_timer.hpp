#pragma once
// GPU time per pass from timestamp queries (where the adapter has the feature): each pass gets
// a begin/end pair; results are resolved into a buffer and read back in milliseconds.
#include <cstdint>
#include <vector>

#include "stipple/renderer/gpu.hpp"

namespace stipple::gpu {

struct PassTimer {
  bool enabled = false;
  uint32_t capacity = 0;  // passes
  QuerySet queries;
  Buffer resolved;
};

PassTimer create_pass_timer(Context& ctx, uint32_t passes);
// Timestamp writes for pass `index`, or null when timing is off (pass it to the descriptor).
const WGPUPassTimestampWrites* pass_timestamps(PassTimer& timer, uint32_t index,
                                               WGPUPassTimestampWrites& storage);
// Records the resolve of the first `passes` passes' queries (all by default) into the timer's
// buffer (end of the frame's encoder).
void resolve_pass_timer(PassTimer& timer, WGPUCommandEncoder encoder, uint32_t passes = UINT32_MAX);
// Blocks until the frame is done; milliseconds per pass (empty when timing is off).
std::vector<double> read_pass_times(Context& ctx, PassTimer& timer);

}  // namespace stipple::gpu
