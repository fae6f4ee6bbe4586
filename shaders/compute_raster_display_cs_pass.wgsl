// Display pass as a compute pass writing the target through a storage binding: on GPUs with
// little fragment throughput (an H200 has few graphics units) a full-screen fragment pass is
// far slower than this. Same shading as the fragment form (display_color). Included by
// compute_raster_display_cs.wgsl and _display_cs_translucent.wgsl.
#include "compute_raster_display_common.wgsl"

@group(0) @binding(3) var target_image: texture_storage_2d<rgba8unorm, write>;

@compute @workgroup_size(16, 16)
fn main(@builtin(global_invocation_id) id: vec3<u32>) {
  if (id.x >= params.width || id.y >= params.height) {
    return;
  }
  textureStore(target_image, vec2<i32>(id.xy), display_color(vec2<i32>(id.xy)));
}
