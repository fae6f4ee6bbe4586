// The display pass as a compute pass, with the translucent points laid over the image.
#include "compute_raster_display_oit.wgsl"
#include "compute_raster_display_cs_pass.wgsl"
