// subgroup_sums() of the accumulation pass (SUBGROUP_SUMS), called by every active thread after
// each word of points. When the open runs with sums of the subgroup's active threads are all on
// one pixel, the subgroup adds their sums (one reduction a channel) and its lowest active thread
// writes the total; the others' runs go on with zero sums, keeping their pixel and depth limit.
// Otherwise each run goes on as it is and is written when it ends. Integer sums: the same totals
// in any order, so the image is the one the per-thread atomics give.
fn subgroup_sums() {
  let has = run_pixel != NO_PIXEL && run_sum.w > 0u;
  let lowest = subgroupMin(select(NO_PIXEL, run_pixel, has));
  if (lowest == NO_PIXEL || subgroupMax(select(0u, run_pixel, has)) != lowest) {
    return;  // no sums, or on more than one pixel
  }
  let entry = subgroupMin(select(0xffffffffu, run_entry, has));
  let total = vec4<u32>(subgroupAdd(select(0u, run_sum.x, has)),
                        subgroupAdd(select(0u, run_sum.y, has)),
                        subgroupAdd(select(0u, run_sum.z, has)),
                        subgroupAdd(select(0u, run_sum.w, has)));
  if (thread_index == subgroupMin(thread_index)) {
    add_run_sums(lowest, entry, total);
  }
  if (has) {
    run_sum = vec4<u32>(0u);
  }
}
