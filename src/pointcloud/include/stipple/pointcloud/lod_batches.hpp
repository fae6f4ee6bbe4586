#pragma once
// LOD batches for streamed data (seed 001, section 3.5): every resident tile of a tileset (or
// node of a COPC file) is a run of batches of its own sizes, quantized on the worker that
// decoded it, in shared GPU arrays of point slots handed out by a free list. Each frame the
// compute rasterizer draws the batches of the tiles the traversal selected: the batch table
// (per-batch box, first index, count) is rebuilt from the selection, the points stay where
// they are. Slots of tiles that leave are reused once the frames that may still read them are
// complete (a FrameFence marked after each frame's submit).
#include <cstdint>
#include <memory>
#include <span>
#include <unordered_map>
#include <vector>

#include "stipple/pointcloud/batches.hpp"
#include "stipple/pointcloud/compute_raster.hpp"
#include "stipple/renderer/frame_fence.hpp"
#include "stipple/renderer/suballocator.hpp"

namespace stipple::pc {

struct LodBatchStore {
  GpuBatchedCloud cloud;      // one segment over every slot; batches: this frame's selection
  gpu::RangeAllocator slots;  // over point slots of the four arrays
  uint64_t capacity = 0;      // point slots
  uint64_t batch_capacity = 0;
  struct Resident {
    uint64_t first = 0;  // first slot
    std::shared_ptr<const BatchedCloud> data;
  };
  std::unordered_map<uint64_t, Resident> resident;  // by key (a tile id)
  struct Deferred {
    uint64_t first = 0, count = 0, frame = 0;  // free once `frame` has completed
  };
  std::vector<Deferred> pending;
  gpu::FrameFence fence;
  uint64_t uploads = 0, frees = 0;
  uint64_t refused = 0;  // uploads that found no room (those tiles are not drawn)
  uint64_t resident_points = 0;
};

// Arrays of `capacity_points` slots (lowered to one storage binding) and a batch table of
// `batch_capacity` entries, grown when a selection needs more.
LodBatchStore create_lod_batch_store(gpu::Context& ctx, uint64_t capacity_points,
                                     uint64_t batch_capacity);

// Uploads `data` under `key`, replacing what the key held. False when no free range holds it
// (the tile is not drawn until room is made).
bool upload_lod_batches(gpu::Context& ctx, LodBatchStore& store, uint64_t key,
                        std::shared_ptr<const BatchedCloud> data);
bool has_lod_batches(const LodBatchStore& store, uint64_t key,
                     const std::shared_ptr<const BatchedCloud>& data);
// The key's slots are reused once the frames submitted so far have completed.
void release_lod_batches(LodBatchStore& store, uint64_t key);
// Frees the slots whose frames have completed (call once a frame, before uploads).
void collect_lod_frees(gpu::Context& ctx, LodBatchStore& store);
// After the frame's submit: slots released from now on wait for it.
void mark_lod_frame_submitted(gpu::Context& ctx, LodBatchStore& store);

// This frame's batches: those of the resident `keys`, in order. The returned cloud is the
// store's and goes to add_compute_raster_passes.
GpuBatchedCloud& select_lod_batches(gpu::Context& ctx, LodBatchStore& store,
                                    std::span<const uint64_t> keys);

}  // namespace stipple::pc
