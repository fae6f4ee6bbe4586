// The display pass as a full-screen triangle, with the translucent points laid over the image.
#include "compute_raster_display_oit.wgsl"
#include "compute_raster_display_fs.wgsl"
