// The 64-bit geometry pass (compute_raster64_pass.wgsl) with the early test on the whole key,
// for RasterKernel::early_key on devices with ShaderInt64AtomicAllOps (wgpu-native).
#include "compute_raster_reduce_none.wgsl"
#include "compute_raster64_early_key.wgsl"
#include "compute_raster64_pass.wgsl"
