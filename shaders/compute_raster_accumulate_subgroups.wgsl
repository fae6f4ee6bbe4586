// The accumulation pass (compute_raster_accumulate_pass.wgsl) with subgroup sums, for
// RasterKernel::subgroup_sums on wgpu-native with subgroups. No `enable subgroups;`: wgpu-native's
// naga (27) refuses the directive and takes the functions without it (as in
// compute_raster64_subgroups.wgsl); Dawn, which needs it, is not given this shader.
#include "compute_raster_sums_subgroups.wgsl"
#include "compute_raster_accumulate_pass.wgsl"
