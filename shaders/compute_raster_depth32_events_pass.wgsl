// The 32-bit fallback's depth pass with winner events (RasterKernel::fallback_events): as
// compute_raster_depth32_pass.wgsl, the nearest depth per pixel by a 32-bit atomicMin, and every
// point that the atomic found no nearer than itself (it lowered the pixel's depth, or tied it)
// also appends an event (pixel, depth, point index) to the event list. The pixel's nearest point
// is among them: raster-events (compute_raster_events.wgsl) picks it out, as the 64-bit key would
// (nearest depth, then lowest index), and the resolve pass colours it, so the fallback needs no
// second pass over the points. The early test lets ties through (as the 64-bit pass does) so
// that a tie with a lower index still gets its event.
//
// The events buffer: EVENT_REGIONS counters, then each region's slots of three words. A pixel's
// events go to region pixel % EVENT_REGIONS, so that the counters' atomics spread over many
// addresses; a region's slots are (arrayLength - EVENT_REGIONS) / 3 / EVENT_REGIONS. A full
// region's counter still counts, which is how raster-events tells an overflow (and then falls
// back to the colour pass). The including shader (compute_raster_depth32_events or
// _depth32_events_plain.wgsl) defines depth_word(pixel), the early test's load.
#include "compute_raster_batch.wgsl"
#include "compute_raster_counted.wgsl"

@group(0) @binding(5) var<storage, read_write> depth_buffer: array<atomic<u32>>;
@group(0) @binding(6) var<storage, read_write> events: array<atomic<u32>>;

const EVENT_REGIONS: u32 = 1024u;

alias Key = vec2<u32>;  // depth bits, point index (segment_base + index)

fn point_key(depth: u32, index: u32) -> vec2<u32> {
  return vec2<u32>(depth, params.segment_base + index);
}

fn append_event(pixel: u32, key: vec2<u32>) {
  let region = pixel % EVENT_REGIONS;
  let slot = atomicAdd(&events[region], 1u);
  let capacity = (arrayLength(&events) - EVENT_REGIONS) / (3u * EVENT_REGIONS);
  if (slot < capacity) {
    let o = EVENT_REGIONS + (region * capacity + slot) * 3u;
    atomicStore(&events[o], pixel);
    atomicStore(&events[o + 1u], key.x);
    atomicStore(&events[o + 2u], key.y);
  }
}

// Only a point that lowered or tied the pixel's depth can be its nearest: it waits for the
// atomic's answer and appends. (Every point past the early test appending, with no wait, listed
// 4x as many events and overflowed at the overview: bench/RESULTS.md, run AA.)
fn write_key(pixel: u32, key: vec2<u32>) {
  if (!ablated(ABLATE_EARLY) && key.x > depth_word(pixel)) {
    return;
  }
  let before = atomicMin(&depth_buffer[pixel], key.x);
  if (key.x <= before) {
    append_event(pixel, key);
  }
}

#include "compute_raster_write.wgsl"
