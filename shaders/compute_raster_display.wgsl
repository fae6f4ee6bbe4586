// The display pass as a full-screen triangle, opaque points only.
#include "compute_raster_display_opaque.wgsl"
#include "compute_raster_display_fs.wgsl"
