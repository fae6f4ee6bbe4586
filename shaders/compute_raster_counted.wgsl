// The batch counters (compute_raster.hpp, RasterCounters) of the passes that count what they
// draw: the depth passes, 64-bit and 32-bit. Included after compute_raster_batch.wgsl.

@group(0) @binding(7) var<storage, read_write> counters: array<atomic<u32>>;

// Called by batch_prologue() on thread 0.
fn count_batch(b: GpuBatch, bits: u32, skipped: bool) {
  if (ablated(ABLATE_COUNT)) {
    return;
  }
  atomicAdd(&counters[C_PROCESSED], 1u);
  if (bits == 0u) {
    atomicAdd(&counters[select(C_CULLED, C_LOD_SKIPPED, skipped)], 1u);
  } else {
    let k = bits / 10u - 1u;
    atomicAdd(&counters[C_RENDERED], 1u);
    atomicAdd(&counters[C_POINTS], b.count);
    atomicAdd(&counters[C_BATCHES_BITS + k], 1u);
    atomicAdd(&counters[C_POINTS_BITS + k], b.count);
  }
}
