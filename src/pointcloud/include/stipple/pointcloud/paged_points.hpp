#pragma once
// Streamed point chunks in shared pages (seed 000, section 3.5) instead of two buffers per chunk:
// each GPU chunk takes a range of a gpu::Suballocator storage pool for its points and one of a
// second pool for its CLOD survivors, at storage-binding-aligned offsets, so the point pipelines
// bind them as they are (per-chunk bind groups at offsets; the shaders do not change). Points
// and survivors live in different pages because WebGPU tracks usage per buffer: the CLOD
// dispatch reads the points and writes the survivors, and one buffer in both roles is a
// read-write conflict even where the ranges are disjoint. Points go in with queue writeBuffer.
// Streaming then creates pages only while the resident set grows, not buffers per tile: freed
// ranges are reused by later tiles.
//
// Frees are deferred: the render thread may have a frame in flight that still reads a range, so
// a freed chunk's range waits until the GPU reports (FrameFence) that every frame submitted
// before the free has completed.
#include <cstdint>
#include <memory>
#include <vector>

#include "stipple/pointcloud/point_cloud.hpp"
#include "stipple/pointcloud/point_renderer.hpp"
#include "stipple/renderer/frame_fence.hpp"
#include "stipple/renderer/suballocator.hpp"

namespace stipple::pc {

struct PagedPointStats {
  uint64_t chunks_uploaded = 0;
  uint64_t ranges_freed = 0;     // given back to the suballocator
  uint64_t buffers_created = 0;  // pages and dedicated buffers made by the suballocator
  uint64_t frees_queued = 0;     // ranges queued to be freed after their frame
};

struct PagedPoints {
  std::unique_ptr<gpu::Suballocator> allocator;
  gpu::FrameFence fence;
  struct PendingFree {
    uint64_t frame;  // fence serial that must complete first
    gpu::SubAllocation range;
  };
  std::vector<PendingFree> pending;
  uint64_t max_chunk_points = 0;  // chunks are split so that their points fit a page
  // Shared with the suballocator's buffer source, which counts what it creates.
  std::shared_ptr<PagedPointStats> stats = std::make_shared<PagedPointStats>();
};

// A store whose pages hold `page_size` bytes (at most the device's maxBufferSize).
PagedPoints create_paged_points(gpu::Context& ctx, uint64_t page_size);

// The pools' usages: points are written by the queue, survivors only by the CLOD pass.
constexpr WGPUBufferUsage kPagedPointUsage = WGPUBufferUsage_Storage | WGPUBufferUsage_CopyDst;
constexpr WGPUBufferUsage kPagedSurvivorUsage = WGPUBufferUsage_Storage;

// Uploads a chunk into page ranges (split where its points exceed a page or a binding) and appends
// the GPU chunks to `cloud`, like upload_chunk.
void upload_chunk_paged(gpu::Context& ctx, PagedPoints& store, GpuPointCloud& cloud,
                        const PointChunk& chunk);
// Queues the ranges of paged chunks for freeing once every frame submitted so far has completed
// (the chunks are cleared; the caller must not draw them again).
void free_chunks_deferred(PagedPoints& store, std::vector<GpuPointCloud::Chunk>& chunks);
// After a frame's submits: the frame's serial, for the ranges freed from now on.
uint64_t mark_frame_submitted(gpu::Context& ctx, PagedPoints& store);
// Polls the device (without blocking) and frees the queued ranges whose frames completed;
// returns how many were freed.
uint32_t collect_frees(gpu::Context& ctx, PagedPoints& store);
// The same with the completed serial given (tests; collect_frees passes the fence's).
uint32_t collect_frees_completed(PagedPoints& store, uint64_t completed);

}  // namespace stipple::pc
