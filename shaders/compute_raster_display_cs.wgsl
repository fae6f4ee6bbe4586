// The display pass as a compute pass, opaque points only.
#include "compute_raster_display_opaque.wgsl"
#include "compute_raster_display_cs_pass.wgsl"
