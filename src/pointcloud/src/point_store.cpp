#include "stipple/pointcloud/point_store.hpp"

#include <algorithm>
#include <chrono>
#include <cstring>

#include "stipple/core/error.hpp"
#include "stipple/math/camera.hpp"
#include "stipple/renderer/shader_preprocessor.hpp"

namespace stipple::pc {
namespace {

struct CompactParams {
  uint32_t total, jobs, row, jobs_at;
};

constexpr uint32_t kCompactWorkgroup = 256;  // vms_compact.wgsl
constexpr uint32_t kRow = 65'535;            // workgroups per dispatch row

// Appends a job, merged into the previous one when both ranges continue it.
void push_job(std::vector<CompactionJob>& jobs, CompactionJob job) {
  if (!jobs.empty()) {
    CompactionJob& last = jobs.back();
    if (last.fresh == job.fresh && last.dst + last.count == job.dst &&
        last.src + last.count == job.src) {
      last.count += job.count;
      return;
    }
  }
  jobs.push_back(job);
}

// The compaction info as the shader reads it: per workgroup of destinations the index of its
// first job (and one more entry), padded to 16 bytes, then the jobs.
uint64_t block_entries(uint64_t points) {
  return (points + kCompactWorkgroup - 1) / kCompactWorkgroup + 1;
}
uint64_t jobs_at(uint64_t points) {
  return (block_entries(points) + 3) & ~uint64_t(3);
}
uint64_t info_bytes_for(uint64_t capacity, uint32_t pointlets) {
  return jobs_at(capacity) * 4 +
         uint64_t(std::max<uint32_t>(pointlets, 1)) * 2 * sizeof(CompactionJob);
}
uint64_t fresh_offset_for(uint64_t capacity, uint32_t pointlets) {
  return (info_bytes_for(capacity, pointlets) + 255) & ~uint64_t(255);
}

}  // namespace

CompactionPlan plan_compaction(const StoreLayout& previous, const std::vector<uint32_t>& wanted,
                               uint64_t max_fresh) {
  CompactionPlan plan;
  plan_compaction(previous, wanted, max_fresh, plan);
  return plan;
}

void plan_compaction(const StoreLayout& previous, const std::vector<uint32_t>& wanted,
                     uint64_t max_fresh, CompactionPlan& plan) {
  const size_t n = wanted.size();
  const bool had = previous.count.size() == n;
  if (!previous.count.empty() && !had)
    fail("plan_compaction: {} pointlets before, {} now", previous.count.size(), n);
  // Every frame plans anew: the vectors keep their capacity (a frame allocates nothing here).
  plan.jobs.clear();
  plan.fresh.clear();
  plan.kept = plan.fresh_points = 0;
  plan.limited = false;
  thread_local std::vector<uint32_t> keep, lack, share;
  keep.resize(n);
  lack.resize(n);
  uint64_t total_lack = 0;
  for (size_t i = 0; i < n; ++i) {
    const uint32_t before = had ? previous.count[i] : 0;
    keep[i] = std::min(before, wanted[i]);
    lack[i] = wanted[i] - keep[i];
    total_lack += lack[i];
  }
  // Too many new points for one transfer: each pointlet gets its share (floor), the remainder
  // one point each in index order, so the whole view refines evenly over the next frames.
  if (total_lack > max_fresh) {
    plan.limited = true;
    uint64_t given = 0;
    share.resize(n);
    for (size_t i = 0; i < n; ++i) {
      share[i] = uint32_t(uint64_t(lack[i]) * max_fresh / total_lack);
      given += share[i];
    }
    for (size_t i = 0; i < n && given < max_fresh; ++i)
      if (share[i] < lack[i]) {
        ++share[i];
        ++given;
      }
    lack.swap(share);
  }
  plan.next.first.assign(n, 0);
  plan.next.count.assign(n, 0);
  uint64_t at = 0, fresh_at = 0;
  for (size_t i = 0; i < n; ++i) {
    const uint32_t count = keep[i] + lack[i];
    if (count == 0) continue;
    if (at + count > UINT32_MAX) fail("plan_compaction: more than 2^32 points in one frame");
    plan.next.first[i] = uint32_t(at);
    plan.next.count[i] = count;
    if (keep[i] > 0) push_job(plan.jobs, {uint32_t(at), previous.first[i], keep[i], 0});
    if (lack[i] > 0) {
      push_job(plan.jobs, {uint32_t(at + keep[i]), uint32_t(fresh_at), lack[i], 1});
      plan.fresh.push_back({uint32_t(i), keep[i], lack[i], uint32_t(fresh_at)});
      fresh_at += lack[i];
    }
    plan.kept += keep[i];
    at += count;
  }
  plan.next.total = at;
  plan.fresh_points = fresh_at;
}

GpuPointStore create_point_store(gpu::Context& ctx, uint64_t capacity, std::vector<Aabb> boxes,
                                 uint64_t staging_bytes) {
  GpuPointStore store;
  store.capacity = capacity;
  store.pointlets = uint32_t(boxes.size());
  store.boxes = std::move(boxes);
  // Every drawn pointlet has a batch, and one more per kBatchPoints of its points.
  const uint64_t batches = capacity / kBatchPoints + store.pointlets + 1;
  for (auto& slab : store.slabs) slab = create_batched_storage(ctx, capacity, batches, "store");
  const uint64_t fresh_offset = fresh_offset_for(capacity, store.pointlets);
  if (staging_bytes < fresh_offset + kStoreWords * 4 * 1024)
    staging_bytes = fresh_offset + kStoreWords * 4 * 1024;  // the info and at least 1,024 points
  constexpr uint64_t kPointBytes = kStoreWords * 4;
  store.fresh_capacity = std::min<uint64_t>((staging_bytes - fresh_offset) / kPointBytes, capacity);
  store.fresh_capacity = std::max<uint64_t>(store.fresh_capacity, 1);
  store.jobs_capacity = uint64_t(std::max<uint32_t>(store.pointlets, 1)) * 2;
  store.staging = gpu::create_staging_ring(ctx, fresh_offset + store.fresh_capacity * kPointBytes,
                                           2, "vms-staging");
  store.fresh = gpu::create_buffer(ctx, store.fresh_capacity * kPointBytes,
                                   WGPUBufferUsage_Storage | WGPUBufferUsage_CopyDst, "vms-fresh");
  store.jobs = gpu::create_buffer(ctx, info_bytes_for(capacity, store.pointlets),
                                  WGPUBufferUsage_Storage | WGPUBufferUsage_CopyDst, "vms-jobs");
  store.params = gpu::create_buffer(
      ctx, sizeof(CompactParams), WGPUBufferUsage_Uniform | WGPUBufferUsage_CopyDst, "vms-params");
  gpu::ShaderModule shader = gpu::create_shader_from_file(ctx, "vms_compact.wgsl");
  store.positions = gpu::create_compute_pipeline(ctx, shader.get(), "compact_positions", nullptr,
                                                 "vms-positions");
  store.colors =
      gpu::create_compute_pipeline(ctx, shader.get(), "compact_colors", nullptr, "vms-colors");
  ctx.check("creating the point store");
  store.gpu_bytes = store.slabs[0].bytes + store.slabs[1].bytes +
                    store.fresh_capacity * kPointBytes + info_bytes_for(capacity, store.pointlets) +
                    sizeof(CompactParams);
  return store;
}

std::vector<Aabb> pointlet_world_boxes(const PointletCache& cache) {
  std::vector<Aabb> boxes;
  boxes.reserve(cache.pointlets().size());
  for (const PointletEntry& e : cache.pointlets()) boxes.push_back(pointlet_world_box(e));
  return boxes;
}

void pointlet_words(const PointletCache& cache, const PointletEntry& pointlet,
                    const Aabb& world_box, std::span<const PointletRecord> records,
                    uint32_t* words) {
  const glm::dvec3 min = world_box.min, size = world_box.max - world_box.min;
  for (const PointletRecord& rec : records) {
    const QuantizedPoint q = quantize(z_up_to_y_up(cache.position(pointlet, rec)), min, size);
    words[0] = q.coarse;
    words[1] = q.medium;
    words[2] = q.fine;
    words[3] = rec.rgba;
    words[4] = rec.attributes;
    words += kStoreWords;
  }
}

uint64_t max_fresh_points(const GpuPointStore& store) {
  return store.fresh_capacity;
}

StoreUpdate update_point_store(gpu::Context& ctx, GpuPointStore& store,
                               const std::vector<uint32_t>& wanted, const FreshWriter& write) {
  if (store.pending.active)
    fail("update_point_store: the previous compaction was never recorded (no vms-compact pass)");
  if (wanted.size() != store.pointlets)
    fail("update_point_store: {} counts for {} pointlets", wanted.size(), store.pointlets);
  // The previous frame's graph has been submitted: its staging slot may be mapped again.
  gpu::staging_submitted(store.staging);
  StoreUpdate out;
  CompactionPlan& plan = store.plan;
  plan_compaction(store.layout, wanted, store.fresh_capacity, plan);
  if (plan.next.total > store.capacity)
    fail("point store: {} points asked for, room for {}", plan.next.total, store.capacity);
  const bool same = plan.fresh_points == 0 && plan.next.count == store.layout.count &&
                    !store.layout.count.empty();
  if (same) {
    out.kept = plan.kept;
    return out;
  }
  auto t = std::chrono::steady_clock::now();
  auto ms_since = [](auto start) {
    return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start)
        .count();
  };
  gpu::StagingWrite w = gpu::begin_staging_write(ctx, store.staging);
  out.wait_ms = ms_since(t);
  t = std::chrono::steady_clock::now();
  const uint64_t fresh_offset = fresh_offset_for(store.capacity, store.pointlets);
  if (plan.jobs.size() > store.jobs_capacity || plan.fresh_points > store.fresh_capacity)
    fail("point store: the compaction info does not fit its buffers");
  {
    // Each workgroup's first job: the job holding its first destination.
    auto* first = reinterpret_cast<uint32_t*>(w.data);
    const uint64_t blocks = block_entries(plan.next.total);
    uint32_t j = 0;
    for (uint64_t b = 0; b < blocks; ++b) {
      const uint64_t d =
          std::min<uint64_t>(b * kCompactWorkgroup, plan.next.total ? plan.next.total - 1 : 0);
      while (j + 1 < plan.jobs.size() && plan.jobs[j + 1].dst <= d) ++j;
      first[b] = j;
    }
    if (!plan.jobs.empty())  // (an empty vector's data() may be null: no memcpy from it)
      std::memcpy(w.data + jobs_at(plan.next.total) * 4, plan.jobs.data(),
                  plan.jobs.size() * sizeof(CompactionJob));
  }
  if (plan.fresh_points > 0) write(plan.fresh, reinterpret_cast<uint32_t*>(w.data + fresh_offset));

  out.write_ms = ms_since(t);
  const uint32_t next = 1 - store.current;
  GpuBatchedCloud& slab = store.slabs[next];
  slab.batches.clear();
  for (uint32_t i = 0; i < store.pointlets; ++i) {
    const uint32_t count = plan.next.count[i];
    if (count == 0) continue;
    const Aabb& box = store.boxes[i];
    for (uint32_t b = 0; b < count; b += kBatchPoints)
      slab.batches.push_back({box.min, box.max - box.min, uint64_t(plan.next.first[i]) + b,
                              std::min<uint32_t>(kBatchPoints, count - b)});
  }
  GpuBatchedCloud::Segment& seg = slab.segments.front();
  seg.first_batch = 0;
  seg.batch_count = uint32_t(slab.batches.size());
  seg.first_point = 0;
  seg.point_count = uint32_t(plan.next.total);
  slab.point_count = plan.next.total;

  store.pending = {true,
                   w,
                   plan.jobs.size(),
                   plan.fresh_points,
                   fresh_offset,
                   store.current,
                   jobs_at(plan.next.total)};
  store.current = next;
  out.changed = true;
  out.kept = plan.kept;
  out.fresh = plan.fresh_points;
  out.limited = plan.limited;
  std::swap(store.layout, plan.next);  // the old layout's vectors serve the next plan
  return out;
}

void add_point_store_pass(gpu::RenderGraph& graph, GpuPointStore& store) {
  graph
      .add_pass(
          "vms-compact", gpu::PassKind::Compute,
          [&store](gpu::PassContext& pc) {
            if (!store.cleared) {
              // Both frames' buffers are written once, so that all the memory they take is
              // in use from the first frame (on a software GPU it is host memory, measured).
              store.cleared = true;
              for (auto& slab : store.slabs)
                for (const gpu::Buffer* b :
                     {&slab.segments.front().coarse, &slab.segments.front().medium,
                      &slab.segments.front().fine, &slab.segments.front().color,
                      &slab.segments.front().attributes})
                  wgpuCommandEncoderClearBuffer(pc.encoder(), b->get(), 0, WGPU_WHOLE_SIZE);
            }
            GpuPointStore::Pending& p = store.pending;
            if (!p.active) return;
            p.active = false;
            gpu::end_staging_write(store.staging, p.write);
            gpu::Context& ctx = pc.gpu();
            WGPUCommandEncoder encoder = pc.encoder();
            const uint64_t total = store.layout.total;
            if (total == 0) return;
            wgpuCommandEncoderCopyBufferToBuffer(
                encoder, p.write.buffer, 0, store.jobs.get(), 0,
                p.jobs_at * 4 + p.job_count * sizeof(CompactionJob));
            if (p.fresh_points > 0)
              wgpuCommandEncoderCopyBufferToBuffer(encoder, p.write.buffer, p.fresh_offset,
                                                   store.fresh.get(), 0,
                                                   p.fresh_points * kStoreWords * 4);
            const uint64_t groups = (total + kCompactWorkgroup - 1) / kCompactWorkgroup;
            const uint32_t x = uint32_t(std::min<uint64_t>(groups, kRow));
            const uint32_t y = uint32_t((groups + x - 1) / x);
            const CompactParams params{uint32_t(total), uint32_t(p.job_count),
                                       x * kCompactWorkgroup, uint32_t(p.jobs_at)};
            gpu::write_buffer(ctx, store.params.get(), 0, params);
            const auto& from = store.slabs[p.from].segments.front();
            const auto& to = store.slabs[store.current].segments.front();
            auto positions_layout = gpu::bind_group_layout_of(store.positions);
            auto colors_layout = gpu::bind_group_layout_of(store.colors);
            auto positions = gpu::create_bind_group(
                ctx, positions_layout.get(),
                {gpu::bind_buffer(0, store.params.get()), gpu::bind_buffer(1, store.jobs.get()),
                 gpu::bind_buffer(2, store.fresh.get()), gpu::bind_buffer(3, from.coarse.get()),
                 gpu::bind_buffer(4, from.medium.get()), gpu::bind_buffer(5, from.fine.get()),
                 gpu::bind_buffer(6, to.coarse.get()), gpu::bind_buffer(7, to.medium.get()),
                 gpu::bind_buffer(8, to.fine.get())});
            auto colors = gpu::create_bind_group(
                ctx, colors_layout.get(),
                {gpu::bind_buffer(0, store.params.get()), gpu::bind_buffer(1, store.jobs.get()),
                 gpu::bind_buffer(2, store.fresh.get()), gpu::bind_buffer(3, from.color.get()),
                 gpu::bind_buffer(4, from.attributes.get()), gpu::bind_buffer(6, to.color.get()),
                 gpu::bind_buffer(7, to.attributes.get())});
            auto pass = pc.begin_compute_pass();
            gpu::dispatch(pass.get(), store.positions.get(), {positions.get()}, x, y);
            gpu::dispatch(pass.get(), store.colors.get(), {colors.get()}, x, y);
            wgpuComputePassEncoderEnd(pass.get());
          })
      .side_effect();
}

}  // namespace stipple::pc
