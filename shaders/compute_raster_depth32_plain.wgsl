// compute_raster_depth32_pass.wgsl with the early test's plain load (wgpu-native).
#include "compute_raster_depth32_early_plain.wgsl"
#include "compute_raster_depth32_pass.wgsl"
