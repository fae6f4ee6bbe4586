// The 64-bit geometry pass (compute_raster64_pass.wgsl) with subgroup operations, for
// RasterKernel::subgroup_reduce on devices with subgroups. No `enable subgroups;`: wgpu-native's
// naga (27) refuses the directive and takes the functions without it; the 64-bit pass runs on
// wgpu-native only (Dawn has no 64-bit atomics), which is the only place this shader is made.
#include "compute_raster_reduce_subgroups.wgsl"
#include "compute_raster64_early_word.wgsl"
#include "compute_raster64_pass.wgsl"
