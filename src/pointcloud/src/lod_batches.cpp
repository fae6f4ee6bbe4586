#include "stipple/pointcloud/lod_batches.hpp"

#include <algorithm>

#include "stipple/core/error.hpp"

namespace stipple::pc {

LodBatchStore create_lod_batch_store(gpu::Context& ctx, uint64_t capacity_points,
                                     uint64_t batch_capacity) {
  const uint64_t max_bytes = std::min<uint64_t>(
      {ctx.limits.maxStorageBufferBindingSize, ctx.limits.maxBufferSize, 1ull << 31});
  LodBatchStore store;
  store.capacity = std::max<uint64_t>(1, std::min(capacity_points, max_bytes / 4));
  store.batch_capacity = std::max<uint64_t>(batch_capacity, 64);
  store.cloud = create_batched_storage(ctx, store.capacity, store.batch_capacity, "lod-batches");
  store.slots = gpu::RangeAllocator(store.capacity);
  auto& seg = store.cloud.segments.front();
  seg.point_count = uint32_t(store.capacity);  // indices into every slot are valid
  seg.batch_count = 0;
  return store;
}

bool has_lod_batches(const LodBatchStore& store, uint64_t key,
                     const std::shared_ptr<const BatchedCloud>& data) {
  auto it = store.resident.find(key);
  return it != store.resident.end() && it->second.data == data;
}

void release_lod_batches(LodBatchStore& store, uint64_t key) {
  auto it = store.resident.find(key);
  if (it == store.resident.end()) return;
  const uint64_t count = it->second.data->point_count();
  if (count > 0) store.pending.push_back({it->second.first, count, store.fence.submitted()});
  store.resident_points -= count;
  store.resident.erase(it);
  ++store.frees;
}

bool upload_lod_batches(gpu::Context& ctx, LodBatchStore& store, uint64_t key,
                        std::shared_ptr<const BatchedCloud> data) {
  if (has_lod_batches(store, key, data)) return true;
  release_lod_batches(store, key);
  const uint64_t n = data->point_count();
  uint64_t first = 0;
  if (n > 0) {
    first = store.slots.allocate(n);
    if (first == gpu::RangeAllocator::npos) {
      ++store.refused;
      return false;
    }
    const auto& seg = store.cloud.segments.front();
    const uint64_t at = first * 4, bytes = n * 4;
    gpu::write_buffer(ctx, seg.coarse.get(), at, data->coarse.data(), bytes);
    gpu::write_buffer(ctx, seg.medium.get(), at, data->medium.data(), bytes);
    gpu::write_buffer(ctx, seg.fine.get(), at, data->fine.data(), bytes);
    gpu::write_buffer(ctx, seg.color.get(), at, data->color.data(), bytes);
    gpu::write_buffer(ctx, seg.attributes.get(), at, data->attributes.data(), bytes);
  }
  store.resident_points += n;
  store.resident[key] = {first, std::move(data)};
  ++store.uploads;
  return true;
}

void collect_lod_frees(gpu::Context& ctx, LodBatchStore& store) {
  if (store.pending.empty()) return;
  ctx.poll(false);
  const uint64_t completed = store.fence.completed();
  std::erase_if(store.pending, [&](const LodBatchStore::Deferred& d) {
    if (d.frame > completed) return false;
    store.slots.free(d.first, d.count);
    return true;
  });
}

void mark_lod_frame_submitted(gpu::Context& ctx, LodBatchStore& store) {
  store.fence.mark(ctx);
}

GpuBatchedCloud& select_lod_batches(gpu::Context& ctx, LodBatchStore& store,
                                    std::span<const uint64_t> keys) {
  GpuBatchedCloud& cloud = store.cloud;
  cloud.batches.clear();
  cloud.point_count = 0;
  for (uint64_t key : keys) {
    auto it = store.resident.find(key);
    if (it == store.resident.end()) continue;
    for (Batch b : it->second.data->batches) {
      b.first += it->second.first;
      cloud.batches.push_back(b);
    }
    cloud.point_count += it->second.data->point_count();
  }
  // The resolve finds a point's batch by binary search over first indices.
  std::sort(cloud.batches.begin(), cloud.batches.end(),
            [](const Batch& a, const Batch& b) { return a.first < b.first; });
  auto& seg = cloud.segments.front();
  if (cloud.batches.size() > store.batch_capacity) {
    store.batch_capacity = cloud.batches.size() * 2;
    seg.batches =
        gpu::create_buffer(ctx, store.batch_capacity * kGpuBatchBytes,
                           WGPUBufferUsage_Storage | WGPUBufferUsage_CopyDst, "lod-batch-table");
  }
  seg.batch_count = uint32_t(cloud.batches.size());
  seg.first_batch = 0;
  seg.first_point = 0;
  return cloud;
}

}  // namespace stipple::pc
