#include "stipple/pointcloud/paged_points.hpp"

#include <algorithm>

#include "stipple/core/error.hpp"
#include "stipple/renderer/gpu.hpp"

namespace stipple::pc {
PagedPoints create_paged_points(gpu::Context& ctx, uint64_t page_size) {
  PagedPoints store;
  gpu::BufferSource source = gpu::device_buffer_source(ctx);
  source.create = [create = std::move(source.create), stats = store.stats](
                      uint64_t size, WGPUBufferUsage usage, bool dedicated) {
    ++stats->buffers_created;
    return create(size, usage, dedicated);
  };
  gpu::SuballocatorOptions options = gpu::suballocator_options(ctx, page_size);
  store.allocator = std::make_unique<gpu::Suballocator>(std::move(source), options);
  // A chunk's points must fit one page (so that no chunk gets a dedicated buffer).
  store.max_chunk_points =
      std::min<uint64_t>(max_gpu_chunk_points(ctx), page_size / sizeof(PointChunk::Vertex));
  if (store.max_chunk_points == 0) fail("paged points: page size {} is too small", page_size);
  return store;
}

void upload_chunk_paged(gpu::Context& ctx, PagedPoints& store, GpuPointCloud& cloud,
                        const PointChunk& chunk) {
  append_chunk_pieces(
      cloud, chunk, store.max_chunk_points,
      [&](GpuPointCloud::Chunk& c, const PointChunk::Vertex* vertices) {
        const uint64_t point_bytes = uint64_t(c.count) * sizeof(PointChunk::Vertex);
        c.range = store.allocator->allocate(point_bytes, kPagedPointUsage);
        c.survivors_range = store.allocator->allocate(uint64_t(c.count) * 4, kPagedSurvivorUsage);
        c.points_buffer = c.range.buffer;
        c.points_offset = c.range.offset;
        c.survivors_buffer = c.survivors_range.buffer;
        c.survivors_offset = c.survivors_range.offset;
        // writeBuffer sizes must be multiples of 4: 20-byte vertices always are.
        gpu::write_buffer(ctx, c.points_buffer, c.points_offset, vertices, point_bytes);
        ++store.stats->chunks_uploaded;
      });
}

void free_chunks_deferred(PagedPoints& store, std::vector<GpuPointCloud::Chunk>& chunks) {
  for (auto& c : chunks)
    for (const gpu::SubAllocation& range : {c.range, c.survivors_range})
      if (range) {
        store.pending.push_back({store.fence.submitted(), range});
        ++store.stats->frees_queued;
      }
  chunks.clear();
}

uint64_t mark_frame_submitted(gpu::Context& ctx, PagedPoints& store) {
  return store.fence.mark(ctx);
}

uint32_t collect_frees_completed(PagedPoints& store, uint64_t completed) {
  uint32_t freed = 0;
  auto keep = std::remove_if(store.pending.begin(), store.pending.end(),
                             [&](const PagedPoints::PendingFree& f) {
                               if (f.frame > completed) return false;
                               store.allocator->free(f.range);
                               ++freed;
                               return true;
                             });
  store.pending.erase(keep, store.pending.end());
  store.stats->ranges_freed += freed;
  return freed;
}

uint32_t collect_frees(gpu::Context& ctx, PagedPoints& store) {
  if (store.pending.empty()) return 0;
  ctx.poll(false);
  return collect_frees_completed(store, store.fence.completed());
}

}  // namespace stipple::pc
