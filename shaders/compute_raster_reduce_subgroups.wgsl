// subgroup_write() for the 64-bit geometry pass (SUBGROUP_REDUCE): at overview distances the
// consecutive points of a Morton-sorted batch, which are consecutive invocations, fall on one
// pixel, and their early tests and atomics all go to one address, where the hardware takes them
// one after another. When every shown point of the subgroup's active invocations is on one
// pixel, the subgroup finds their nearest key (the smallest depth, then the smallest index at
// it: the key order of the visibility buffer, so the image is the same) and the invocation
// holding it writes it; otherwise each writes its own. Called by every active invocation (not
// only the shown ones), so that the subgroup operations see them all.
fn subgroup_write(shown: bool, pixel: u32, key: Key) {
  let lowest = subgroupMin(select(NO_PIXEL, pixel, shown));
  if (lowest == NO_PIXEL) {
    return;  // none shown
  }
  if (subgroupMax(select(0u, pixel, shown)) != lowest) {
    if (shown) {
      write_key(pixel, key);
    }
    return;
  }
  let depth = subgroupMin(select(0xffffffffu, key_depth(key), shown));
  let index = subgroupMin(select(0xffffffffu, key_index(key), shown && key_depth(key) == depth));
  // The invocation holding that key writes it (keys are unique: they hold the point's index).
  if (shown && key_depth(key) == depth && key_index(key) == index) {
    write_key(pixel, key);
  }
}
