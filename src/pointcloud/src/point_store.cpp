#include "stipple/pointcloud/point_store.hpp"

#include <algorithm>
#include <chrono>
#include <cstring>

#include "stipple/core/error.hpp"
#include "stipple/core/thread_pool.hpp"
#include "stipple/math/camera.hpp"
#include "stipple/renderer/shader_preprocessor.hpp"

namespace stipple::pc {
namespace {

struct CompactParams {
  uint32_t total, jobs, row, jobs_at;
};

constexpr uint32_t kCompactWorkgroup = 256;  // vms_compact.wgsl
constexpr uint32_t kRow = 65'535;            // workgroups per dispatch row

// Pointlets a piece of the plan: jobs merge within a piece, never across one, so the plan is
// the same on any number of threads.
constexpr size_t kPlanPiece = 8192;

// What a piece of pointlets adds to the plan (counted first, so pieces are placed in parallel).
struct PieceCounts {
  uint64_t points = 0, fresh = 0, kept = 0, jobs = 0, ranges = 0;
  bool changed = false;  // a pointlet's count differs from the previous frame's
};

// Whether a job continues the piece's last one: kept points when the last job kept the range
// just before them in the previous buffers, new points after new points (consecutive in staging).
struct JobMerge {
  bool any = false, last_fresh = false;
  uint64_t kept_end = 0;
  bool kept(uint32_t src, uint32_t count) {
    const bool continues = any && !last_fresh && kept_end == src;
    any = true;
    last_fresh = false;
    kept_end = uint64_t(src) + count;
    return continues;
  }
  bool fresh() {
    const bool continues = any && last_fresh;
    any = last_fresh = true;
    return continues;
  }
};

// A pointlet's points kept from the previous frame, and its new ones (all it lacks, or its share
// of a bounded transfer).
struct PointletStep {
  uint32_t before, keep, lack;
};
PointletStep step_of(const StoreLayout& previous, bool had, const std::vector<uint32_t>& wanted,
                     const uint32_t* share, size_t i) {
  const uint32_t before = had ? previous.count[i] : 0;
  const uint32_t keep = std::min(before, wanted[i]);
  return {before, keep, share ? share[i] : wanted[i] - keep};
}

void count_piece(const StoreLayout& previous, bool had, const std::vector<uint32_t>& wanted,
                 const uint32_t* share, size_t begin, size_t end, PieceCounts& c) {
  JobMerge merge;
  for (size_t i = begin; i < end; ++i) {
    const PointletStep s = step_of(previous, had, wanted, share, i);
    c.changed |= s.keep + s.lack != s.before;
    c.points += s.keep + s.lack;
    c.kept += s.keep;
    c.fresh += s.lack;
    if (s.keep > 0 && !merge.kept(previous.first[i], s.keep)) ++c.jobs;
    if (s.lack > 0) {
      ++c.ranges;
      if (!merge.fresh()) ++c.jobs;
    }
  }
}

// Writes a piece's layout, jobs and new ranges from where the pieces before it end (`at`).
void place_piece(const StoreLayout& previous, bool had, const std::vector<uint32_t>& wanted,
                 const uint32_t* share, size_t begin, size_t end, const PieceCounts& at,
                 CompactionPlan& plan) {
  JobMerge merge;
  uint64_t point = at.points, fresh = at.fresh;
  size_t job = at.jobs, range = at.ranges;
  for (size_t i = begin; i < end; ++i) {
    const PointletStep s = step_of(previous, had, wanted, share, i);
    const uint32_t count = s.keep + s.lack;
    plan.next.first[i] = count > 0 ? uint32_t(point) : 0;
    plan.next.count[i] = count;
    if (s.keep > 0) {
      const uint32_t src = previous.first[i];
      if (merge.kept(src, s.keep))
        plan.jobs[job - 1].count += s.keep;
      else
        plan.jobs[job++] = {uint32_t(point), src, s.keep, 0};
    }
    if (s.lack > 0) {
      if (merge.fresh())
        plan.jobs[job - 1].count += s.lack;
      else
        plan.jobs[job++] = {uint32_t(point + s.keep), uint32_t(fresh), s.lack, 1};
      plan.fresh[range++] = {uint32_t(i), s.keep, s.lack, uint32_t(fresh)};
      fresh += s.lack;
    }
    point += count;
  }
}

// body(begin, end) over [0, count) in pieces of `grain`, on the pool's threads and the
// caller's when there is a pool.
template <typename Body>
void for_each_range(ThreadPool* pool, size_t count, size_t grain, Body&& body) {
  if (!pool || count <= grain) {
    if (count > 0) body(size_t(0), count);
    return;
  }
  pool->parallel_for(count, grain, [&body](size_t begin, size_t end) { body(begin, end); });
}

// The pieces of kPlanPiece pointlets of `n`.
size_t plan_pieces(size_t n) {
  return (n + kPlanPiece - 1) / kPlanPiece;
}
// body(k, first, end) for each piece k of `n` pointlets: [first, end) its pointlets.
template <typename Body>
void for_each_piece(ThreadPool* pool, size_t n, Body&& body) {
  for_each_range(pool, plan_pieces(n), 1, [&](size_t begin, size_t end) {
    for (size_t k = begin; k < end; ++k) body(k, k * kPlanPiece, std::min(n, (k + 1) * kPlanPiece));
  });
}
constexpr size_t kBlockPiece = 16384;  // workgroups' first jobs looked up a piece
constexpr size_t kJobPiece = 32768;    // jobs copied into staging a piece

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
                               uint64_t max_fresh, ThreadPool* pool) {
  CompactionPlan plan;
  plan_compaction(previous, wanted, max_fresh, plan, pool);
  return plan;
}

void plan_compaction(const StoreLayout& previous, const std::vector<uint32_t>& wanted,
                     uint64_t max_fresh, CompactionPlan& plan, ThreadPool* pool) {
  const size_t n = wanted.size();
  const bool had = previous.count.size() == n;
  if (!previous.count.empty() && !had)
    fail("plan_compaction: {} pointlets before, {} now", previous.count.size(), n);
  // Every frame plans anew: the vectors keep their capacity (a frame allocates nothing here).
  plan.limited = false;
  const size_t pieces = plan_pieces(n);
  // (Named through references: a thread_local named in a lambda is the running thread's.)
  thread_local std::vector<PieceCounts> counts_storage, at_storage;
  std::vector<PieceCounts>& counts = counts_storage;
  std::vector<PieceCounts>& at = at_storage;
  counts.assign(pieces, {});
  at.resize(pieces);
  const uint32_t* share = nullptr;
  auto count_all = [&] {
    for_each_piece(pool, n, [&](size_t k, size_t first, size_t end) {
      counts[k] = {};
      count_piece(previous, had, wanted, share, first, end, counts[k]);
    });
  };
  count_all();
  uint64_t total_lack = 0;
  for (const PieceCounts& c : counts) total_lack += c.fresh;
  // Too many new points for one transfer: each pointlet gets its share (floor), the remainder
  // one point each in index order, so the whole view refines evenly over the next frames.
  if (total_lack > max_fresh) {
    plan.limited = true;
    thread_local std::vector<uint32_t> shares;
    shares.resize(n);
    auto lack_of = [&](size_t i) {
      return wanted[i] - std::min(had ? previous.count[i] : 0u, wanted[i]);
    };
    uint64_t given = 0;
    for (size_t i = 0; i < n; ++i) {
      shares[i] = uint32_t(uint64_t(lack_of(i)) * max_fresh / total_lack);
      given += shares[i];
    }
    for (size_t i = 0; i < n && given < max_fresh; ++i)
      if (shares[i] < lack_of(i)) {
        ++shares[i];
        ++given;
      }
    share = shares.data();
    count_all();
  }
  // Where each piece starts: the sums of the pieces before it.
  PieceCounts total;
  for (size_t k = 0; k < pieces; ++k) {
    at[k] = total;
    total.points += counts[k].points;
    total.fresh += counts[k].fresh;
    total.kept += counts[k].kept;
    total.jobs += counts[k].jobs;
    total.ranges += counts[k].ranges;
    total.changed |= counts[k].changed;
  }
  if (total.points > UINT32_MAX) fail("plan_compaction: more than 2^32 points in one frame");
  plan.next.first.resize(n);
  plan.next.count.resize(n);
  plan.jobs.resize(total.jobs);
  plan.fresh.resize(total.ranges);
  for_each_piece(pool, n, [&](size_t k, size_t first, size_t end) {
    place_piece(previous, had, wanted, share, first, end, at[k], plan);
  });
  plan.next.total = total.points;
  plan.fresh_points = total.fresh;
  plan.kept = total.kept;
  plan.changed = total.changed || !had;
}

GpuPointStore create_point_store(gpu::Context& ctx, uint64_t capacity, std::vector<Aabb> boxes,
                                 uint64_t staging_bytes, uint32_t staging_slots) {
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
                                           std::max(staging_slots, 2u), "vms-staging");
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

namespace {

double ms_since(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start)
      .count();
}

// Plans the update into store.plan; false when the layout stays as it is (`out` then says
// what is kept).
bool plan_update(GpuPointStore& store, const std::vector<uint32_t>& wanted, ThreadPool* pool,
                 StoreUpdate& out) {
  if (wanted.size() != store.pointlets)
    fail("update_point_store: {} counts for {} pointlets", wanted.size(), store.pointlets);
  CompactionPlan& plan = store.plan;
  plan_compaction(store.layout, wanted, store.fresh_capacity, plan, pool);
  if (plan.next.total > store.capacity)
    fail("point store: {} points asked for, room for {}", plan.next.total, store.capacity);
  if (!plan.changed && !store.layout.count.empty()) {
    out.kept = plan.kept;
    return false;
  }
  return true;
}

// Writes store.plan into the mapped slot `w` (the compaction info, the new points) and the
// batches of the slab the frames do not draw, and makes the plan the store's layout; the update
// the next graph records is out.pending. Touches nothing a frame reads while it draws.
void write_planned_update(GpuPointStore& store, const gpu::StagingWrite& w,
                          const FreshWriter& write, ThreadPool* pool, StoreUpdate& out) {
  CompactionPlan& plan = store.plan;
  auto t = std::chrono::steady_clock::now();
  const uint64_t fresh_offset = fresh_offset_for(store.capacity, store.pointlets);
  if (plan.jobs.size() > store.jobs_capacity || plan.fresh_points > store.fresh_capacity)
    fail("point store: the compaction info does not fit its buffers");
  {
    // Each workgroup's first job: the job holding its first destination (the jobs are sorted
    // by destination and cover every one), looked up per workgroup on every core.
    auto* first = reinterpret_cast<uint32_t*>(w.data);
    const uint64_t blocks = block_entries(plan.next.total);
    const std::vector<CompactionJob>& jobs = plan.jobs;
    const uint64_t last = plan.next.total ? plan.next.total - 1 : 0;
    for_each_range(pool, blocks, kBlockPiece, [&](size_t begin, size_t end) {
      for (size_t b = begin; b < end; ++b) {
        const uint64_t d = std::min<uint64_t>(b * kCompactWorkgroup, last);
        const auto after =
            std::upper_bound(jobs.begin(), jobs.end(), d,
                             [](uint64_t dst, const CompactionJob& job) { return dst < job.dst; });
        first[b] = uint32_t(after == jobs.begin() ? 0 : after - jobs.begin() - 1);
      }
    });
    auto* job_words = w.data + jobs_at(plan.next.total) * 4;
    for_each_range(pool, jobs.size(), kJobPiece, [&](size_t begin, size_t end) {
      std::memcpy(job_words + begin * sizeof(CompactionJob), jobs.data() + begin,
                  (end - begin) * sizeof(CompactionJob));
    });
  }
  if (plan.fresh_points > 0) write(plan.fresh, reinterpret_cast<uint32_t*>(w.data + fresh_offset));

  out.write_ms = ms_since(t);
  const uint32_t next = 1 - store.current;
  GpuBatchedCloud& slab = store.slabs[next];
  // A batch per kBatchPoints of each drawn pointlet, in pointlet order: counted per piece of
  // pointlets, then written from each piece's start in parallel.
  const size_t pieces = plan_pieces(store.pointlets);
  thread_local std::vector<uint64_t> batch_at_storage;
  std::vector<uint64_t>& batch_at = batch_at_storage;  // (the workers see this thread's)
  batch_at.assign(pieces + 1, 0);
  for_each_piece(pool, store.pointlets, [&](size_t k, size_t first, size_t end) {
    uint64_t batches = 0;
    for (size_t i = first; i < end; ++i)
      batches += (plan.next.count[i] + kBatchPoints - 1) / kBatchPoints;
    batch_at[k + 1] = batches;
  });
  for (size_t k = 0; k < pieces; ++k) batch_at[k + 1] += batch_at[k];
  slab.batches.resize(batch_at[pieces]);
  for_each_piece(pool, store.pointlets, [&](size_t k, size_t first, size_t end) {
    Batch* batch = slab.batches.data() + batch_at[k];
    for (size_t i = first; i < end; ++i) {
      const uint32_t count = plan.next.count[i];
      if (count == 0) continue;
      const Aabb& box = store.boxes[i];
      const glm::dvec3 size = box.max - box.min;
      for (uint32_t b = 0; b < count; b += kBatchPoints)
        *batch++ = {box.min, size, uint64_t(plan.next.first[i]) + b,
                    std::min<uint32_t>(kBatchPoints, count - b)};
    }
  });
  GpuBatchedCloud::Segment& seg = slab.segments.front();
  seg.first_batch = 0;
  seg.batch_count = uint32_t(slab.batches.size());
  seg.first_point = 0;
  seg.point_count = uint32_t(plan.next.total);
  slab.point_count = plan.next.total;

  out.pending = {true,
                 w,
                 plan.jobs.size(),
                 plan.fresh_points,
                 fresh_offset,
                 store.current,
                 jobs_at(plan.next.total),
                 plan.next.total};
  out.changed = true;
  out.kept = plan.kept;
  out.fresh = plan.fresh_points;
  out.limited = plan.limited;
  std::swap(store.layout, plan.next);  // the old layout's vectors serve the next plan
}

}  // namespace

StoreUpdate update_point_store(gpu::Context& ctx, GpuPointStore& store,
                               const std::vector<uint32_t>& wanted, const FreshWriter& write,
                               ThreadPool* pool) {
  if (store.pending.active)
    fail("update_point_store: the previous compaction was never recorded (no vms-compact pass)");
  // The previous frame's graph has been submitted: its staging slot may be mapped again.
  gpu::staging_submitted(store.staging);
  StoreUpdate out;
  if (!plan_update(store, wanted, pool, out)) return out;
  const auto t = std::chrono::steady_clock::now();
  const gpu::StagingWrite w = gpu::begin_staging_write(ctx, store.staging);
  out.wait_ms = ms_since(t);
  write_planned_update(store, w, write, pool, out);
  commit_point_store_update(store, out);
  return out;
}

StoreUpdate prepare_point_store_update(GpuPointStore& store, const std::vector<uint32_t>& wanted,
                                       const FreshWriter& write, const gpu::StagingWrite& w,
                                       ThreadPool* pool) {
  StoreUpdate out;
  if (plan_update(store, wanted, pool, out)) write_planned_update(store, w, write, pool, out);
  return out;
}

void commit_point_store_update(GpuPointStore& store, const StoreUpdate& update) {
  if (!update.changed) return;
  if (store.pending.active)
    fail("point store: the previous compaction was never recorded (no vms-compact pass)");
  store.pending = update.pending;
  store.current = 1 - store.current;
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
            const uint64_t total = p.total;  // the layout may be planned again meanwhile
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
