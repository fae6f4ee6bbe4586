// The 64-bit geometry pass (compute_raster64_pass.wgsl) for devices without subgroups.
#include "compute_raster_reduce_none.wgsl"
#include "compute_raster64_early_word.wgsl"
#include "compute_raster64_pass.wgsl"
