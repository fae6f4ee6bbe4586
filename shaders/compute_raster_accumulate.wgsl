// The accumulation pass (compute_raster_accumulate_pass.wgsl) without subgroup operations.
#include "compute_raster_sums_none.wgsl"
#include "compute_raster_accumulate_pass.wgsl"
