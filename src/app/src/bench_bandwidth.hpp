#pragma once
// Memory bandwidth bounds for the benches, measured on the device they run on: what a compute
// shader reaches reading a large buffer (the bound of a kernel that reads its points once), and
// what copyBufferToBuffer reaches (read + write traffic; not a shader's bound).
#include <cstdint>

#include "stipple/renderer/gpu.hpp"

namespace stipple::app {

struct ReadBandwidth {
  double gb_per_s = 0;  // best over the workgroup counts tried
  uint32_t workgroups = 0;
  uint64_t bytes = 0;
};
// Reads `bytes` (capped by the device's binding limits) with a grid-stride kernel; 0 GB/s when
// the adapter has no timestamp queries.
ReadBandwidth read_bandwidth(gpu::Context& ctx, uint64_t bytes);
// GB copied per second (each byte is read once and written once).
double copy_bandwidth_gbs(gpu::Context& ctx, uint64_t bytes);

}  // namespace stipple::app
