// subgroup_write() where the device has no subgroups: each point writes for itself.
// SUBGROUP_REDUCE (compute_raster_write.wgsl) is then left off; this only keeps the shader whole.
fn subgroup_write(shown: bool, pixel: u32, key: Key) {
  if (shown) {
    write_key(pixel, key);
  }
}
