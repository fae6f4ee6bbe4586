// compute_raster_depth32_pass.wgsl with the early test's atomic load (Dawn, browsers).
#include "compute_raster_depth32_early_atomic.wgsl"
#include "compute_raster_depth32_pass.wgsl"
