#include "stipple/pointcloud/virtual_cloud.hpp"

#include <malloc.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstdlib>
#include <cstring>
#include <ctime>
#include <functional>
#include <future>
#include <memory>
#include <mutex>
#include <numeric>
#include <optional>
#include <string_view>
#include <thread>
#include <vector>

#include <fmt/format.h>

#include "stipple/core/error.hpp"
#include "stipple/core/log.hpp"
#include "stipple/core/memory.hpp"
#include "stipple/core/thread_pool.hpp"
#include "stipple/engine/camera.hpp"
#include "stipple/engine/engine.hpp"
#include "stipple/engine/render_plugins.hpp"
#include "stipple/pointcloud/batches.hpp"
#include "stipple/pointcloud/compute_raster.hpp"
#include "stipple/pointcloud/point_cloud_plugin.hpp"
#include "stipple/pointcloud/point_store.hpp"
#include "stipple/pointcloud/scene.hpp"
#include "stipple/renderer/gpu.hpp"

namespace stipple::pc {
namespace {

using Clock = std::chrono::steady_clock;

// The process's resident memory once malloc has handed its free memory back (a cache build
// leaves hundreds of MiB free in its arenas): a baseline of what is in use.
uint64_t trimmed_resident_bytes() {
#ifdef __GLIBC__
  if (!std::getenv("STIPPLE_NO_MALLOC_TRIM")) malloc_trim(0);
#endif
  return resident_bytes();
}
double ms_since(Clock::time_point t) {
  return std::chrono::duration<double, std::milli>(Clock::now() - t).count();
}

// CPU time of the calling thread (ms), where the platform has it: unlike wall time, not
// lengthened by other threads and processes taking the cores.
double thread_cpu_ms() {
#ifdef CLOCK_THREAD_CPUTIME_ID
  timespec t{};
  if (clock_gettime(CLOCK_THREAD_CPUTIME_ID, &t) == 0)
    return double(t.tv_sec) * 1e3 + t.tv_nsec * 1e-6;
#endif
  return 0;
}

}  // namespace

// The host side of the virtual memory system (seed 002, III-C): per pointlet, the loaded
// prefix of its (shuffled) points, held as the point store's words (kStoreWords a point, as many
// bytes as a cache record): a load task converts what it reads, so a frame's new points are
// copied to staging as they are, and the conversion runs on the loaders, off the frame. Load tasks
// on a worker pool grow a prefix to what the LoD asks for, up to 25% more while the host budget
// allows; prefixes no longer asked for shrink when the budget runs short. A task re-checks the
// state it was made for, so a stale task does nothing.
//
// No lock per pointlet: a pointlet has one load in flight at most, and only that task writes its
// prefix meanwhile (the selection unloads only pointlets not in flight, on its own thread: the
// frame's, or the selector's with async_selection; one selection at a time). A
// load reads and converts outside any lock, into a new buffer of exactly the new size (a vector
// grown by doubling would hold up to twice what is counted), and swaps it in under
// `buffers_mutex`, which the frame's new-point copy holds while it reads the buffers (once a
// frame, not once a pointlet). What the frame scans every selection (loaded counts, in-flight
// flags, buffer addresses) lies in arrays of its own, a few bytes a pointlet.
static_assert(sizeof(PointletRecord) == kStoreWords * 4, "budgets count a point as its record");
struct VirtualResidency {
  std::shared_ptr<const PointletCache> cache;
  std::vector<Aabb> boxes;  // per pointlet, world space: what the store quantizes against
  size_t count = 0;
  // Per pointlet: the loaded prefix (kStoreWords words a point, `loaded` points), whether a load
  // is in flight.
  std::unique_ptr<std::unique_ptr<uint32_t[]>[]> words;
  std::unique_ptr<std::atomic<uint32_t>[]> loaded;
  std::unique_ptr<std::atomic<bool>[]> in_flight;
  std::mutex buffers_mutex;  // held to replace a pointlet's buffer, and while a frame copies
  uint64_t budget = 0;       // bytes of records
  std::atomic<uint64_t> bytes{0}, loads{0}, points_read{0};
  uint64_t unloaded_since_trim = 0;  // the selection's: record bytes freed since the last trim
  std::atomic<uint32_t> pending{0};
  std::mutex progress_mutex;
  std::condition_variable progress;
  std::atomic<uint64_t> completed{0};  // load tasks finished (a new selection is due)
  std::mutex finished_mutex;
  std::vector<uint32_t> finished;  // pointlets whose load ended since the selection took them
  std::string error;               // the first failed load (under progress_mutex)

  explicit VirtualResidency(std::shared_ptr<const PointletCache> c)
      : cache(std::move(c)),
        boxes(pointlet_world_boxes(*cache)),
        count(cache->pointlets().size()),
        words(std::make_unique<std::unique_ptr<uint32_t[]>[]>(count)),
        loaded(std::make_unique<std::atomic<uint32_t>[]>(count)),
        in_flight(std::make_unique<std::atomic<bool>[]>(count)) {}

  // `keep` points of pointlet `index`'s prefix (at most what it holds) in a buffer of their own.
  std::unique_ptr<uint32_t[]> resized(uint32_t index, uint32_t keep, uint32_t size) const {
    if (size == 0) return nullptr;
    auto out = std::make_unique_for_overwrite<uint32_t[]>(uint64_t(size) * kStoreWords);
    if (keep > 0) std::memcpy(out.get(), words[index].get(), uint64_t(keep) * kStoreWords * 4);
    return out;
  }
  void load(uint32_t index, uint32_t target) {
    try {
      const uint32_t have = loaded[index].load();  // only this task changes it while in flight
      if (target > have) {
        thread_local std::vector<PointletRecord> records;
        records.clear();
        cache->read(index, have, target - have, records);
        if (records.size() != target - have)
          fail("pointlet {}: {} points read, {} asked for", index, records.size(), target - have);
        std::unique_ptr<uint32_t[]> grown = resized(index, have, target);
        pointlet_words(*cache, cache->pointlets()[index], boxes[index], records,
                       grown.get() + uint64_t(have) * kStoreWords);
        {
          std::lock_guard lock(buffers_mutex);
          words[index].swap(grown);
          loaded[index].store(target);
        }
        grown.reset();  // the old buffer, freed outside the lock
        bytes += uint64_t(target - have) * sizeof(PointletRecord);
        points_read += target - have;
        ++loads;
      }
    } catch (const std::exception& e) {
      std::lock_guard lock(progress_mutex);
      if (error.empty()) error = e.what();
    }
    in_flight[index].store(false);
    {
      // Before `completed` moves: a selection that sees the count has this pointlet to visit.
      std::lock_guard lock(finished_mutex);
      finished.push_back(index);
    }
    --pending;
    ++completed;
    progress.notify_all();
  }
  // By the selection, for a pointlet not in flight.
  void unload(uint32_t index, uint32_t keep) {
    const uint32_t have = loaded[index].load();
    if (keep >= have) return;
    std::unique_ptr<uint32_t[]> shrunk = resized(index, keep, keep);
    {
      std::lock_guard lock(buffers_mutex);
      words[index].swap(shrunk);
      loaded[index].store(keep);
    }
    bytes -= uint64_t(have - keep) * sizeof(PointletRecord);
    unloaded_since_trim += uint64_t(have - keep) * sizeof(PointletRecord);
  }
};

namespace {

// The LoD of a view: its camera and target size (what a LoD result was computed for).
struct LodView {
  ExtractedCamera camera;
  uint32_t width = 0, height = 0;
};

// Render-world resource.
struct VirtualCloudRender {
  std::shared_ptr<VirtualResidency> residency;
  std::vector<uint32_t> desired;  // the last LoD
  std::vector<uint32_t> draw;     // what the host holds of it (reused every frame)
  // The selection is incremental: per pointlet what its last visit saw (the LoD's count and what
  // was missing of it), sums over every pointlet kept up to date from those, and the pointlets
  // to visit next time besides those whose count changed (loads the budget had no room for).
  std::vector<uint32_t> seen_want, seen_lack;
  std::vector<uint8_t> marked;
  std::vector<uint32_t> touched, waiting, finished;
  std::vector<std::vector<uint32_t>> lacking_pieces;  // per piece of touched: what to load
  uint64_t lacking = 0, wanted = 0;                   // points: sum of seen_lack, of seen_want
  uint32_t visible = 0;                               // pointlets with seen_want > 0
  std::vector<uint32_t> incoming;                     // a LoD result as it arrives
  uint64_t selected_after = 0;  // residency.completed when the drawn selection was built
  VirtualCloudOptions options;
  CloudAttributes attributes;  // the cache's: which colour modes it can show, default ramps
  std::unique_ptr<GpuPointlets> pointlets;
  std::unique_ptr<PointletLodPipeline> lod;
  std::unique_ptr<ComputeRasterPipeline> raster;
  WGPUTextureFormat format = WGPUTextureFormat_Undefined;
  // Boxed: the graph reads it when it executes.
  std::unique_ptr<GpuPointStore> store;
  bool transfer_pending = false;  // the last update could not bring every new point
  double lod_gpu_ms = 0;          // this frame's LoD, when it ran
  bool process_measured = false;  // the process budget has been turned into a points budget
  // Under a process budget: the baseline and the point store's share of it (the store's
  // buffers are resident only once written); what the process holds besides its points is
  // never taken as less. The first selection loads nothing, so that the first frame's own
  // memory (pipelines, the target) is measured before points take the rest.
  uint64_t held_before_points = 0;
  bool loads_held = false;
  std::unique_ptr<gpu::ReadbackRing> lod_ring;  // LoD counts back from the GPU, unwaited
  bool have_lod = false, lod_due = false;
  uint64_t lod_tag = 0;
  std::array<LodView, 8> lod_views;  // by tag: what each LoD in flight was computed for
  LodView desired_for, lod_requested_for;
  std::unique_ptr<ThreadPool> pool;      // load tasks (disk reads)
  std::unique_ptr<ThreadPool> workers;   // the frame's own parallel work: new points for the GPU
  std::optional<uint64_t> incoming_tag;  // a LoD result in `incoming` that no selection took yet
  // async_selection: the selection in flight on `selector`'s thread, with its own copy of the
  // stats and the store update it prepared; the frame that finds it done commits both.
  std::future<void> job;
  bool lod_unused = false;  // a LoD taken while the selection waited for its staging slot
  VirtualCloudStats job_stats;
  StoreUpdate job_update;
  double job_wait_ms = 0;  // mapping its staging slot, on the frame's thread
  // Last, so destroyed first: a selection in flight ends before what it uses goes.
  std::unique_ptr<ThreadPool> selector;
};

// Touched pointlets a piece of the selection's visits on the frame's workers.
constexpr size_t kVisitPiece = 4096;

bool same_view(const ExtractedCamera& a, const ExtractedCamera& b) {
  return a.position == b.position && a.rotation == b.rotation && a.fov_y == b.fov_y &&
         a.near_plane == b.near_plane;
}

// The new points of an update, copied from the pointlets' host buffers. They are a few points
// each of tens of thousands of pointlets, so the copy costs per range (the pointlet's buffer and
// its words are cache misses), not per byte: the ranges are shared among every core as soon as
// there are more than a piece of them, the calling thread taking its share.
FreshWriter fresh_writer(VirtualResidency& r, ThreadPool& pool) {
  return [&r, &pool](std::span<const FreshRange> ranges, uint32_t* words) {
    auto copy = [&](size_t begin, size_t end) {
      for (size_t k = begin; k < end; ++k) {
        const FreshRange& f = ranges[k];
        const uint32_t held = r.loaded[f.pointlet].load(std::memory_order_relaxed);
        if (held < uint64_t(f.first) + f.count)
          fail("virtual memory: pointlet {} holds {} points, {} asked for", f.pointlet, held,
               uint64_t(f.first) + f.count);
        std::memcpy(words + uint64_t(f.at) * kStoreWords,
                    r.words[f.pointlet].get() + uint64_t(f.first) * kStoreWords,
                    uint64_t(f.count) * kStoreWords * 4);
      }
    };
    // No pointlet's buffer is replaced while they are read (loads wait to swap theirs in).
    std::lock_guard lock(r.buffers_mutex);
    pool.parallel_for(ranges.size(), 2048, copy);
  };
}

// Per frame (in Queue: this frame's target is known then): when the view changed, the LoD on
// the GPU says what each pointlet should draw; loads are requested for what is missing and
// unloads free what is not needed when the host budget runs short; the frame draws what is
// loaded of it, and a new selection follows when loads complete.
// The bucket the GPU can hold: each point costs 40 bytes (20 in each of the two frames'
// buffers), the staging copy and the compaction info come on top; one array of the bucket must
// fit a storage binding.
uint64_t fit_bucket(gpu::Context& ctx, const VirtualCloudOptions& options, uint32_t pointlets,
                    uint64_t pointlet_bytes) {
  uint64_t bucket = options.bucket;
  const uint64_t binding = std::min<uint64_t>(
      {ctx.limits.maxStorageBufferBindingSize, ctx.limits.maxBufferSize, uint64_t(1) << 31});
  if (bucket * 4 > binding) {
    STIPPLE_WARN("--bucket {} exceeds one storage binding of this device ({} MiB): using {}",
                 bucket, binding >> 20, binding / 4);
    bucket = binding / 4;
  }
  if (options.gpu_budget > 0) {
    const uint64_t fixed = pointlet_bytes + uint64_t(pointlets) * 2 * (16 + 32) +
                           std::min(options.staging_bytes, bucket * kStoreWords * 4) +
                           (uint64_t(1) << 20);
    const uint64_t per_point = 2 * kStoreWords * 4 + 2 * 32 / kBatchPoints + 1;  // and batches
    const uint64_t fits = options.gpu_budget > fixed ? (options.gpu_budget - fixed) / per_point : 0;
    if (fits == 0)
      fail("--gpu-memory {} MiB holds not even the pointlets' buffers", options.gpu_budget >> 20);
    if (fits < bucket) {
      STIPPLE_WARN("--bucket {} does not fit --gpu-memory {} MiB: using {}", bucket,
                   options.gpu_budget >> 20, fits);
      bucket = fits;
    }
  }
  return std::max<uint64_t>(bucket, 1);
}

// Seed 002, Fig. 15: GPU ms of the last frame's passes in five stages.
void gather_stage_times(const RenderStats& frame, double lod_ms, VirtualCloudStats& stats) {
  auto ms = [&frame](std::initializer_list<const char*> passes) {
    double sum = 0;
    for (const char* pass : passes)
      if (auto it = frame.pass_ms.find(pass); it != frame.pass_ms.end()) sum += it->second;
    return sum;
  };
  stats.stage_ms = {lod_ms + ms({"pointlet-lod"}), ms({"vms-compact"}), ms({"raster-depth"}),
                    ms({"raster-resolve", "raster-accumulate"}),
                    ms({"raster-clear", "raster-occlusion", "raster-fill", "raster-display"})};
}

// What the frames add to the baseline once they run (the driver's pipelines, the targets,
// tables that grow): 40-60 MiB measured on lavapipe.
constexpr uint64_t kFrameGrowth = uint64_t(64) << 20;
// Host bytes a drawn point costs: its record, and a quarter more read ahead.
constexpr uint64_t kHostPointBytes = sizeof(PointletRecord) * 5 / 4;

uint64_t store_host_bytes(uint64_t bucket, uint64_t pointlets, uint64_t staging_bytes,
                          bool device_in_host, uint32_t slots);

// Fails when the process budget leaves no room for even the smallest selection (its point
// store and points), naming the least that works.
void check_process_budget(const VirtualCloudOptions& options, uint64_t baseline,
                          uint64_t point_count, uint64_t pointlets, std::string_view holding) {
  const uint64_t points =
      std::min<uint64_t>(kMinimumBudgetPoints, std::max<uint64_t>(point_count, 1));
  const uint64_t minimum =
      minimum_process_budget(baseline + kFrameGrowth +
                             store_host_bytes(points, pointlets, options.staging_bytes,
                                              options.device_in_host, staging_slots(options)) +
                             points * kHostPointBytes);
  if (options.process_budget < minimum)
    fail(
        "--host-memory {} MiB is below what this process needs: {} MiB are resident before any "
        "point loads (the device{} {}); at least {} MiB are needed to draw points",
        options.process_budget >> 20, baseline >> 20,
        options.device_in_host ? ", whose buffers are host memory on this CPU adapter," : "",
        holding, (minimum + (1 << 20) - 1) >> 20);
}

// What the point store of a bucket takes of the host (a sizing estimate that follows
// create_point_store): its mapped staging slots, each the compaction info and new points,
// and on a CPU adapter also its device buffers (both frames' point words and batches, the new
// points and the info).
uint64_t store_host_bytes(uint64_t bucket, uint64_t pointlets, uint64_t staging_bytes,
                          bool device_in_host, uint32_t slots) {
  const uint64_t info = (bucket / 256 + 8) * 4 + (pointlets + 1) * 32;
  const uint64_t slot = std::max(staging_bytes, info + 256 + kStoreWords * 4 * 1024);
  const uint64_t fresh = std::min<uint64_t>(slot - info, bucket * kStoreWords * 4);
  const uint64_t device =
      2 * (bucket * kStoreWords * 4 + (bucket / kBatchPoints + pointlets + 1) * 32) + fresh + info;
  return slots * (info + 256 + fresh) + (device_in_host ? device : 0);
}

// Turns the process budget into the parts it pays for, once the baseline (what the process
// holds before points load) is known: a budget that leaves no room for even the smallest
// selection is an error naming the least that works; on a CPU adapter without --gpu-memory the
// bucket is lowered so that its point store (host memory there) and its points on the host
// (with a quarter more read ahead) fit what the baseline leaves.
void plan_process_budget(VirtualCloudOptions& options, const VirtualResidency& r,
                         uint64_t baseline) {
  check_process_budget(options, baseline, r.cache->info().point_count, r.count,
                       "and the cache's tables");
  if (!options.device_in_host || options.gpu_budget > 0) return;
  // What the frames add once they run is measured then; the bucket leaves room for it.
  const uint64_t growth = kFrameGrowth + options.process_budget / 16;
  const uint64_t left = points_budget(options.process_budget, baseline + growth, 0, ~uint64_t(0));
  auto fits = [&](uint64_t bucket) {
    return store_host_bytes(bucket, r.count, options.staging_bytes, true, staging_slots(options)) +
               bucket * kHostPointBytes <=
           left;
  };
  if (fits(options.bucket)) return;
  uint64_t lo = 1, hi = options.bucket;  // fits(lo) holds (check_process_budget), fits(hi) not
  while (hi - lo > 1) {
    const uint64_t mid = lo + (hi - lo) / 2;
    (fits(mid) ? lo : hi) = mid;
  }
  STIPPLE_WARN(
      "--bucket {} does not fit --host-memory {} MiB on this CPU adapter (its buffers "
      "are host memory, {} MiB resident before points): using {}",
      options.bucket, options.process_budget >> 20, baseline >> 20, lo);
  options.bucket = lo;
}

bool same_lod_view(const LodView& a, const ExtractedCamera& camera, uint32_t w, uint32_t h) {
  return same_view(a.camera, camera) && a.width == w && a.height == h;
}

// A selection's work once the LoD is in `v.desired`: the process budget, the pointlets to visit,
// unloads, loads, and the point store's update for what is loaded (`update_store`, given what
// each pointlet draws). Only this work starts loads and unloads. It reads and writes `v`'s
// selection state, the residency and `stats`, never the GPU context, so it may run on a thread of
// its own (async_selection). Returns whether loads were requested.
bool run_selection(VirtualCloudRender& v, VirtualCloudStats& stats, bool lod_new,
                   const std::function<StoreUpdate(const std::vector<uint32_t>&)>& update_store) {
  VirtualResidency& r = *v.residency;
  auto t = Clock::now();
  // The process budget: measured from the second selection on (the first runs before the
  // first frame made the GPU buffers), and again at every selection, since the rest of the
  // process grows as the flight goes on (driver, tables). It only ever lowers the points'
  // budget, so the view does not thin and thicken back and forth.
  if (v.options.process_budget > 0 && stats.selections >= 1) {
    uint64_t rss = resident_bytes();
    const uint64_t loaded = r.bytes.load();
#ifdef __GLIBC__
    // Freed and regrown record buffers leave free memory in malloc's arenas, resident: when the
    // process holds more besides its points than planned, it goes back first, so that the
    // points' budget is not lowered for memory nobody uses (which would free more of it).
    if (rss > v.held_before_points + loaded + (uint64_t(16) << 20) &&
        !std::getenv("STIPPLE_NO_MALLOC_TRIM")) {
      const auto t_trim = Clock::now();
      malloc_trim(0);
      stats.trim_ms += ms_since(t_trim);
      r.unloaded_since_trim = 0;
      rss = resident_bytes();
    }
#endif
    if (rss > 0) {
      const uint64_t left = points_budget(
          v.options.process_budget, std::max(rss, v.held_before_points + loaded), loaded, r.budget);
      if (left < r.budget) {
        if (!v.process_measured || left + r.budget / 20 < r.budget)
          STIPPLE_INFO(
              "host budget: the process holds {} MiB besides its points; {} MiB left for them",
              (rss - std::min(rss, r.bytes.load())) >> 20, left >> 20);
        r.budget = left;
      }
      v.process_measured = true;
    }
  }
  stats.host_budget = r.budget;
  stats.process_bytes = resident_bytes();
  const uint64_t completed = r.completed.load();
  // Which pointlets to visit: those whose LoD count changed, whose load ended, or that waited
  // for room in the budget; every one at the first selection. The others keep their state (a
  // pointlet's loaded prefix only changes by its load, or by an unload here), so a frame's work
  // follows what changed, not the number of pointlets.
  const auto& table = v.residency->cache->pointlets();
  std::vector<uint32_t>& touched = v.touched;
  touched.clear();
  auto touch = [&](uint32_t i) {
    if (!v.marked[i]) {
      v.marked[i] = 1;
      touched.push_back(i);
    }
  };
  if (v.seen_want.size() != r.count) {
    v.draw.assign(r.count, 0);
    v.seen_want.assign(r.count, 0);
    v.seen_lack.assign(r.count, 0);
    v.marked.assign(r.count, 0);
    v.lacking = v.wanted = v.visible = 0;
    v.waiting.clear();
    for (uint32_t i = 0; i < r.count; ++i) touch(i);
  } else {
    if (lod_new)
      for (uint32_t i = 0; i < r.count; ++i)
        if (v.desired[i] != v.seen_want[i]) touch(i);
    {
      std::lock_guard lock(r.finished_mutex);
      v.finished.swap(r.finished);
    }
    for (uint32_t i : v.finished) touch(i);
    v.finished.clear();
    for (uint32_t i : v.waiting) touch(i);
    v.waiting.clear();
  }
  // What a visit learns of a pointlet: the sums move by the difference to its last visit. The
  // touched pointlets are visited in pieces on the frame's workers (tens of thousands a frame
  // when the view zooms), each piece summing its own moves (modulo 2^64, so in any order).
  struct Moves {
    uint64_t lacking = 0, wanted = 0;
    uint32_t visible = 0;
  };
  auto visit = [&](uint32_t i, Moves& m) {
    const uint32_t want = v.desired[i], have = r.loaded[i].load();
    const uint32_t lack = want > have ? want - have : 0;
    m.lacking += uint64_t(lack) - v.seen_lack[i];
    m.wanted += uint64_t(want) - v.seen_want[i];
    m.visible += uint32_t(want > 0) - uint32_t(v.seen_want[i] > 0);
    v.seen_lack[i] = lack;
    v.seen_want[i] = want;
  };
  std::vector<Moves> moves;
  auto visit_pieces = [&](auto&& each) {
    const size_t pieces = (touched.size() + kVisitPiece - 1) / kVisitPiece;
    moves.assign(pieces, {});
    v.workers->parallel_for(pieces, 1, [&](size_t begin, size_t end) {
      for (size_t k = begin; k < end; ++k)
        for (size_t t = k * kVisitPiece; t < std::min(touched.size(), (k + 1) * kVisitPiece); ++t)
          each(k, touched[t]);
    });
    for (const Moves& m : moves) {
      v.lacking += m.lacking;
      v.wanted += m.wanted;
      v.visible += m.visible;
    }
  };
  visit_pieces([&](size_t k, uint32_t i) { visit(i, moves[k]); });
  // Unload first: what the view no longer needs goes when what it needs would not fit.
  const uint64_t needed = v.lacking * sizeof(PointletRecord);
  for (uint32_t i = 0; i < r.count && r.bytes.load() + needed > r.budget; ++i)
    if (!r.in_flight[i].load() && r.loaded[i].load() > v.desired[i]) {
      r.unload(i, v.desired[i]);
      touch(i);
    }
  // Still over (the budget was lowered under what the view holds): every pointlet keeps the
  // same share of its prefix, so the view thins out evenly.
  if (const uint64_t bytes = r.bytes.load(); bytes > r.budget) {
    const double share = double(r.budget) / double(bytes);
    for (uint32_t i = 0; i < r.count; ++i)
      if (!r.in_flight[i].load()) {
        r.unload(i, uint32_t(double(r.loaded[i].load()) * share));
        touch(i);
      }
  }
  // Freed pointlet buffers stay in malloc's arenas (loads allocate on the workers, unloads free
  // on this thread), resident but unused: past 256 MiB of them they are handed back, so the
  // process budget measures what is in use.
  if (r.unloaded_since_trim > (uint64_t(256) << 20) && !std::getenv("STIPPLE_NO_MALLOC_TRIM")) {
    const auto t_trim = std::chrono::steady_clock::now();
#ifdef __GLIBC__
    malloc_trim(0);
#endif
    stats.trim_ms += ms_since(t_trim);
    r.unloaded_since_trim = 0;
  }
#ifdef __GLIBC__
  // Sampled: mallinfo2 walks every arena's free lists (milliseconds with millions of chunks).
  if (stats.selections % 64 == 1) stats.heap_free_bytes = mallinfo2().fordblks;
#endif
  // Loads for what is missing (with up to 25% more while the budget allows), and what to draw.
  // Loads go to the pool as a few tasks per worker (a task per pointlet costs more to queue than
  // many reads take), the pointlets that lack most first in every task.
  const auto residency_start = Clock::now();
  struct Load {
    uint32_t index, goal, lack;
  };
  std::vector<Load> loads;
  std::vector<uint32_t>& draw = v.draw;
  uint64_t planned = r.bytes.load();
  // In index order, as a full pass would take them: the budget goes to the same pointlets.
  // Rebuilt from the marks (a byte scan, cheaper than a sort) when loads, the waiting or unloads
  // added to it out of order.
  if (!std::is_sorted(touched.begin(), touched.end())) {
    touched.clear();
    for (uint32_t i = 0; i < r.count; ++i)
      if (v.marked[i]) touched.push_back(i);
  }
  // Visited and drawn in pieces on the workers; those that lack points and are not in flight
  // (in flight: visited when done) are then taken in index order on this thread, where the
  // budget is planned. Only this thread starts loads and unloads, so what such a pointlet holds
  // does not change in between.
  const size_t load_pieces = (touched.size() + kVisitPiece - 1) / kVisitPiece;
  v.lacking_pieces.resize(std::max(v.lacking_pieces.size(), load_pieces));
  for (size_t k = 0; k < load_pieces; ++k) v.lacking_pieces[k].clear();
  visit_pieces([&](size_t k, uint32_t i) {
    v.marked[i] = 0;
    visit(i, moves[k]);
    const uint32_t want = v.desired[i], have = r.loaded[i].load();
    draw[i] = std::min(want, have);
    if (want > have && !r.in_flight[i].load()) v.lacking_pieces[k].push_back(i);
  });
  for (size_t k = 0; k < load_pieces; ++k)
    for (uint32_t i : v.lacking_pieces[k]) {
      const uint32_t want = v.desired[i], have = r.loaded[i].load();
      if (v.loads_held) {  // the first selection loads nothing: visited again at the next
        v.waiting.push_back(i);
        continue;
      }
      const uint32_t extra = std::min<uint32_t>(table[i].count, want + want / 4);
      uint32_t goal =
          planned + uint64_t(extra - have) * sizeof(PointletRecord) <= r.budget ? extra : want;
      if (planned + uint64_t(goal - have) * sizeof(PointletRecord) > r.budget) {
        v.waiting.push_back(i);  // full: tried again at the next selection
        continue;
      }
      planned += uint64_t(goal - have) * sizeof(PointletRecord);
      r.in_flight[i].store(true);
      ++r.pending;
      loads.push_back({i, goal, want - have});
    }
  const bool requested = !loads.empty();
  if (requested) {
    std::stable_sort(loads.begin(), loads.end(),
                     [](const Load& a, const Load& b) { return a.lack > b.lack; });
    const size_t tasks = std::min<size_t>(loads.size(), size_t(v.pool->size()) * 2);
    for (size_t task = 0; task < tasks; ++task) {
      std::vector<std::pair<uint32_t, uint32_t>> chunk;
      for (size_t k = task; k < loads.size(); k += tasks)
        chunk.emplace_back(loads[k].index, loads[k].goal);
      v.pool->submit([keep = v.residency, chunk = std::move(chunk)] {
        for (const auto& [index, goal] : chunk) keep->load(index, goal);
      });
    }
  }
  stats.residency_ms = ms_since(residency_start);
  t = Clock::now();
  const StoreUpdate update = update_store(draw);
  stats.upload_ms = ms_since(t);
  v.transfer_pending = update.limited;
  stats.staging_wait_ms = update.wait_ms;
  stats.fresh_write_ms = update.write_ms;
  stats.kept_points = update.kept;
  stats.new_points = update.fresh;
  stats.gpu_bytes = v.store->gpu_bytes + v.pointlets->bytes;
  stats.staging_bytes = gpu::staging_bytes(v.store->staging);
  stats.selected_points = v.store->layout.total;
  stats.visible_pointlets = v.visible;
  stats.desired_points = v.wanted;
  stats.host_bytes = r.bytes.load();
  stats.peak_host_bytes = std::max(stats.peak_host_bytes, stats.host_bytes);
  stats.pending_loads = r.pending.load();
  stats.loads = r.loads.load();
  stats.points_read = r.points_read.load();
  stats.touched_pointlets = uint32_t(touched.size());
  ++stats.selections;
  stats.bucket = v.options.bucket;
  v.selected_after = completed;
  return requested;
}

// async_selection: starts run_selection on the selector's thread, with a staging slot mapped
// here (mapping needs the device, which only this thread drives). The frames go on drawing the
// current buffers; the first frame that finds it done commits its update and stats.
void launch_selection(gpu::Context& ctx, VirtualCloudRender& v, VirtualCloudStats& stats,
                      bool lod_new) {
  const auto t = Clock::now();
  const gpu::StagingWrite w = gpu::begin_staging_write(ctx, v.store->staging);
  v.job_wait_ms = ms_since(t);
  if (!v.selector) v.selector = std::make_unique<ThreadPool>(1);
  v.job_stats = stats;
  v.job_update = {};
  v.job = v.selector->submit([&v, w, lod_new] {
    const auto start = Clock::now();
    VirtualResidency& r = *v.residency;
    run_selection(v, v.job_stats, lod_new, [&](const std::vector<uint32_t>& draw) {
      v.job_update = prepare_point_store_update(*v.store, draw, fresh_writer(r, *v.workers), w,
                                                v.workers.get());
      return v.job_update;
    });
    v.job_stats.async_select_ms = ms_since(start);
  });
  stats.settled = false;
}

void select_points(Registry& render) {
  auto& v = render.resource<VirtualCloudRender>();
  const auto& target = render.resource<RenderTarget>();
  const ExtractedCamera* extracted = first_extracted_camera(render);
  if (!extracted || !target.valid()) return;
  VirtualResidency& r = *v.residency;
  auto& stats = render.resource<VirtualCloudStats>();
  {
    std::lock_guard lock(r.progress_mutex);
    if (!r.error.empty()) fail("{}", r.error);
  }
  gpu::Context& ctx = *render.resource<GpuContext>();
  if (!v.pointlets) {
    v.pointlets = std::make_unique<GpuPointlets>(upload_pointlets(ctx, *v.residency->cache));
    v.lod = std::make_unique<PointletLodPipeline>(create_pointlet_lod_pipeline(ctx));
    v.lod_ring = std::make_unique<gpu::ReadbackRing>(
        gpu::create_readback_ring(ctx, uint64_t(std::max<size_t>(r.count, 1)) * 4, 3));
    // The baseline: what the process holds with the device, the cache's tables and the
    // pointlets' buffers up, before any point loads.
    const uint64_t baseline = v.options.process_budget > 0 ? trimmed_resident_bytes() : 0;
    if (v.options.process_budget > 0 && baseline > 0) plan_process_budget(v.options, r, baseline);
    v.options.bucket = fit_bucket(ctx, v.options, uint32_t(r.count), v.pointlets->bytes);
    v.store = std::make_unique<GpuPointStore>(create_point_store(
        ctx, v.options.bucket, r.boxes, v.options.staging_bytes, staging_slots(v.options)));
    if (v.options.process_budget > 0 && baseline > 0) {
      // What the store takes of the process budget: its mapped staging, and on a CPU adapter
      // its buffers (host memory that is not resident until first written, so not measured
      // yet). The points get the rest.
      const uint64_t store = gpu::staging_bytes(v.store->staging) +
                             (v.options.device_in_host ? v.store->gpu_bytes : 0);
      v.held_before_points = baseline + store;
      r.budget = points_budget(v.options.process_budget, v.held_before_points, 0, r.budget);
      STIPPLE_INFO(
          "host budget: {} MiB resident before points, {} MiB for the point store (B = "
          "{}), {} MiB for the points",
          baseline >> 20, store >> 20, v.options.bucket, r.budget >> 20);
    }
    if (v.options.gpu_budget > 0 && v.store->gpu_bytes + v.pointlets->bytes > v.options.gpu_budget)
      fail("--gpu-memory {} MiB is too small for the point store ({} MiB at B = {})",
           v.options.gpu_budget >> 20, (v.store->gpu_bytes + v.pointlets->bytes) >> 20,
           v.options.bucket);
  }
  // The LoD runs in the frame's graph and comes back without a wait: a frame uses the newest
  // result that arrived (usually the previous frame's view). The first has nothing to use yet
  // and runs one at once. Results are taken every frame, also while a selection runs on its
  // own thread (which reads `desired`), so that the ring stays free for the newest view.
  auto t = Clock::now();
  gpu::readback_submitted(*v.lod_ring);  // the previous frame's graph has been submitted
  v.incoming.resize(r.count);
  if (auto tag = gpu::take_readback(ctx, *v.lod_ring, v.incoming.data(), false))
    v.incoming_tag = tag;
  // The slot the last commit used can be mapped again once its frame is submitted; asked for
  // now, not at the next start, so that the next selection need not wait for it.
  if (v.options.async_selection && v.store) gpu::staging_submitted(v.store->staging);
  if (v.job.valid()) {
    // async_selection: the frame draws what the last selection made until the next is done.
    v.lod_due = !same_lod_view(v.lod_requested_for, *extracted, target.width, target.height);
    stats.lod_ms = ms_since(t);
    if (v.job.wait_for(std::chrono::seconds(0)) != std::future_status::ready) {
      stats.settled = false;
      return;
    }
    v.job.get();  // the selection's error, if it failed
    stats = v.job_stats;
    stats.staging_wait_ms = v.job_wait_ms;
    commit_point_store_update(*v.store, v.job_update);
    v.job_update = {};
  }
  bool lod_new = v.lod_unused;
  if (v.incoming_tag) {
    v.desired.swap(v.incoming);
    v.desired_for = v.lod_views[*v.incoming_tag % v.lod_views.size()];
    v.incoming_tag.reset();
    lod_new = true;
  } else if (!v.have_lod) {
    v.desired = compute_pointlet_lod(ctx, *v.lod, *v.pointlets, to_camera(*extracted), target.width,
                                     target.height, v.options.bucket, &v.lod_gpu_ms);
    v.desired_for = {*extracted, target.width, target.height};
    v.lod_requested_for = v.desired_for;
    lod_new = true;
  }
  v.have_lod = true;
  stats.lod_ms = ms_since(t);
  // A LoD for this view goes into this frame's graph (queue_virtual_cloud adds it).
  v.lod_due = !same_lod_view(v.lod_requested_for, *extracted, target.width, target.height);
  const bool loads_done = r.completed.load() != v.selected_after;
  const bool current = same_lod_view(v.desired_for, *extracted, target.width, target.height);
  const bool first_held = v.loads_held;
  v.loads_held = v.options.process_budget > 0 && stats.selections == 0;
  if (!lod_new && !loads_done && !v.transfer_pending && !first_held) {
    stats.settled =
        r.pending.load() == 0 && current && !v.lod_due && !gpu::readback_busy(*v.lod_ring);
    return;
  }
  if (v.options.async_selection) {
    // The selection starts once its staging slot is mapped (its last copy done on the GPU), so
    // that this thread never waits for the GPU; until then the frames draw the last one.
    // (A new LoD waits with it; the other reasons to select last until a selection runs.)
    if (!gpu::staging_write_ready(v.store->staging)) {
      v.lod_unused = lod_new;
      stats.settled = false;
      return;
    }
    v.lod_unused = false;
    launch_selection(ctx, v, stats, lod_new);
    return;
  }
  const bool requested = run_selection(v, stats, lod_new, [&](const std::vector<uint32_t>& draw) {
    return update_point_store(ctx, *v.store, draw, fresh_writer(r, *v.workers), v.workers.get());
  });
  stats.settled = !requested && !v.loads_held && stats.pending_loads == 0 && !v.transfer_pending &&
                  current && !v.lod_due && !gpu::readback_busy(*v.lod_ring);
}

void queue_virtual_cloud(Registry& render) {
  auto& fg = render.resource<FrameGraph>();
  if (!fg.active || !render.try_resource<VirtualCloudRender>()) return;  // still building
  auto& v = render.resource<VirtualCloudRender>();
  v.lod_gpu_ms = 0;
  const auto select_start = Clock::now();
  const double select_cpu = thread_cpu_ms();
  select_points(render);
  render.resource<VirtualCloudStats>().select_ms = ms_since(select_start);
  render.resource<VirtualCloudStats>().select_cpu_ms = thread_cpu_ms() - select_cpu;
  gather_stage_times(render.resource<RenderStats>(), v.lod_gpu_ms,
                     render.resource<VirtualCloudStats>());
  const auto& target = render.resource<RenderTarget>();
  const ExtractedCamera* extracted = first_extracted_camera(render);
  if (!extracted || !v.store) return;
  gpu::Context& ctx = *render.resource<GpuContext>();
  if (!v.raster || v.format != target.format) {
    v.raster =
        std::make_unique<ComputeRasterPipeline>(create_compute_raster_pipeline(ctx, target.format));
    v.format = target.format;
  }
  // The viewer may change the style every frame (extracted with the stats).
  const PointRenderSettings& style = render.resource<PointDrawSettings>().render;
  ComputeRasterOptions options;
  options.hqs = v.options.hqs;
  options.fill_radius = v.options.fill_radius;
  options.occlusion_beta = v.options.occlusion_beta;
  options.background = style.background;
  options.sky = style.sky;
  options.edl_strength = style.edl ? style.edl_strength : 0.0f;
  options.edl_radius = style.edl_radius;
  options.point_size = compute_point_size(style);
  options.shading = point_shading(style, v.attributes);
  options.shading.mode = resolve_color_mode(v.attributes, options.shading.mode);
  options.filter = style.filter;
  options.clip = style.clip;
  options.highlight = style.highlight;
  options.storage_target = (target.usage & WGPUTextureUsage_StorageBinding) != 0;
  if (v.lod_due && gpu::readback_free(*v.lod_ring)) {
    const Camera camera = to_camera(*extracted);
    add_pointlet_lod_passes(fg.graph, *v.lod, *v.pointlets, camera, target.width, target.height,
                            v.options.bucket);
    const uint64_t tag = ++v.lod_tag;
    v.lod_requested_for = {*extracted, target.width, target.height};
    v.lod_views[tag % v.lod_views.size()] = v.lod_requested_for;
    fg.graph
        .add_pass("pointlet-lod-readback", gpu::PassKind::Transfer,
                  [&v, tag](gpu::PassContext& pc) {
                    gpu::record_readback(*v.lod_ring, pc.encoder(), v.pointlets->counts.get(),
                                         uint64_t(v.pointlets->count) * 4, tag);
                  })
        .read("pointlet-counts")
        .side_effect();
  }
  add_point_store_pass(fg.graph, *v.store);
  add_compute_raster_passes(fg.graph, *v.raster, drawn_points(*v.store), to_camera(*extracted),
                            options, target.width, target.height);
  auto& stats = render.resource<RenderStats>();
  stats.points_drawn += drawn_points(*v.store).point_count;
  stats.points_total = v.residency->cache->info().point_count;
}

void extract_virtual_cloud(Registry& main) {
  Registry& render = *main.resource<RenderWorldRef>();
  if (!render.try_resource<VirtualCloudStats>()) return;  // still building (the sample shows)
  main.insert_resource(render.resource<VirtualCloudStats>());
  render.insert_resource(main.resource<PointDrawSettings>());
}

}  // namespace

uint64_t points_budget(uint64_t process_budget, uint64_t resident, uint64_t loaded,
                       uint64_t host_budget) {
  const uint64_t other = resident > loaded ? resident - loaded : 0;
  const uint64_t margin = std::max<uint64_t>(uint64_t(32) << 20, process_budget / 20);
  const uint64_t left = process_budget > other + margin ? process_budget - other - margin : 0;
  return std::min(left, host_budget);
}

uint64_t minimum_process_budget(uint64_t need) {
  // points_budget keeps a margin of 5% of the budget, at least 32 MiB, out of it.
  return std::max(need + (uint64_t(32) << 20), need + need / 19 + 1);
}

void wait_for_virtual_loads(const VirtualCloudHandle& handle, double timeout_s) {
  VirtualResidency& r = *handle.residency;
  std::unique_lock lock(r.progress_mutex);
  const uint64_t seen = r.completed.load();
  r.progress.wait_for(lock, std::chrono::duration<double>(timeout_s),
                      [&] { return r.completed.load() != seen || r.pending.load() == 0; });
}

void fit_virtual_cloud(ViewFit& fit, const VirtualCloudHandle& handle) {
  const PointletCache& cache = *handle.residency->cache;
  const std::vector<PointletEntry>& table = cache.pointlets();
  Aabb all;
  for (const PointletEntry& e : table) all.extend(pointlet_world_box(e));
  if (all.empty()) return;
  std::vector<std::pair<double, uint32_t>> order;
  order.reserve(table.size());
  for (uint32_t i = 0; i < table.size(); ++i)
    if (table[i].count > 0)
      order.emplace_back(glm::length(pointlet_world_box(table[i]).center() - all.center()), i);
  std::sort(order.begin(), order.end(),
            [](const auto& a, const auto& b) { return a.first > b.first; });
  std::vector<PointletRecord> records;
  for (const auto& [distance, i] : order) {
    if (!fit.empty() && !fit.could_widen(pointlet_world_box(table[i]))) continue;
    records.clear();
    cache.read(i, 0, table[i].count, records);
    for (const PointletRecord& r : records) fit.add(z_up_to_y_up(cache.position(table[i], r)));
  }
}

namespace {

// Opens `cache` as the scene's cloud: the main world's scene, settings and handle, the render
// world's residency and pools. `style` is the point style it starts with.
void open_virtual_cloud(Registry& main, Registry& render, const VirtualCloudOptions& options,
                        const PointRenderSettings& style,
                        std::shared_ptr<const PointletCache> cache, bool built,
                        const PointletBuildStats& build_stats) {
  const PointletCacheInfo& info = cache->info();
  if (built)
    STIPPLE_INFO("{}: {} points in {} pointlets of {} ({:.1f} s)", cache->name(), info.point_count,
                 info.pointlet_count, info.pointlet_points, build_stats.seconds);
  else
    STIPPLE_INFO("{}: reused ({} points in {} pointlets)", cache->name(), info.point_count,
                 info.pointlet_count);
  main.insert_resource(VirtualCloudCache{cache->name(), built, build_stats, info.point_count,
                                         info.pointlet_count, info.pointlet_points});
  SceneInfo scene;
  scene.world_bounds.extend(z_up_to_y_up(info.source_bounds.min));
  scene.world_bounds.extend(z_up_to_y_up(info.source_bounds.max));
  scene.points = info.point_count;
  scene.attributes = info.attributes;
  scene.name = options.files.front().filename().string();
  main.insert_resource(scene);
  PointDrawSettings settings;
  settings.render = style;
  settings.compute = true;
  settings.hqs = options.hqs;
  settings.fill_radius = options.fill_radius;
  settings.occlusion_beta = options.occlusion_beta;
  main.insert_resource(settings);
  render.insert_resource(settings);

  auto residency = std::make_shared<VirtualResidency>(cache);
  residency->budget = options.host_budget;
  main.insert_resource(VirtualCloudHandle{residency});
  VirtualCloudRender v;
  v.residency = residency;
  v.options = options;
  v.attributes = info.attributes;
  v.pool = std::make_unique<ThreadPool>(std::max(2u, std::thread::hardware_concurrency()));
  v.workers = std::make_unique<ThreadPool>(std::max(2u, std::thread::hardware_concurrency()));
  render.insert_resource(std::move(v));
  render.insert_resource(VirtualCloudStats{});
  main.insert_resource(VirtualCloudStats{});
}

// The cache building on its own thread (build_in_background), a main-world resource: when the
// engine ends first (the window closed), the build is cancelled and waited for.
struct BackgroundBuild {
  std::thread thread;
  std::shared_ptr<PointletBuildProgress> progress = std::make_shared<PointletBuildProgress>();
  std::atomic<bool> finished{false};
  std::exception_ptr error;  // written before `finished`
  PointletBuildStats stats;  // likewise
  bool built = false;        // likewise (false: another process built it meanwhile)
  std::shared_ptr<const PointletCache> cache;
  Clock::time_point start = Clock::now();
  VirtualCloudOptions options;
  PointRenderSettings style;  // the plugin's: the sample's automatic point size is not kept
  uint64_t frames = 0;        // frames extracted while building (the sample drawn)
  ~BackgroundBuild() {
    progress->cancel = true;
    if (thread.joinable()) thread.join();
  }
};
struct VirtualBackgroundBuild {
  std::shared_ptr<BackgroundBuild> build;
};

// MainStage::Extract, before extract_virtual_cloud: the build's progress for the front end;
// once it is done (and the sample was drawn), the cloud opens and the sample goes.
void activate_virtual_cloud(Registry& main) {
  auto* holder = main.try_resource<VirtualBackgroundBuild>();
  if (!holder || !holder->build) return;
  BackgroundBuild& b = *holder->build;
  auto& progress = main.resource<VirtualCacheProgress>();
  progress.phase = b.progress->phase;
  progress.fraction = b.progress->fraction();
  progress.seconds = ms_since(b.start) / 1e3;
  if (!b.finished || b.frames == 0) {
    ++b.frames;
    return;
  }
  b.thread.join();
  if (b.error) std::rethrow_exception(b.error);
  Registry& render = *main.resource<RenderWorldRef>();
  // The sample leaves this frame: its render twin's points go now (the render world is idle at
  // the sync point), the twin itself at the next sync.
  remove_point_clouds(main, render);
  // The style as the user left it (colour, EDL, filters), the point size as the options give
  // it: the sample's was fitted to its sparser points.
  PointRenderSettings style = main.resource<PointDrawSettings>().render;
  style.point_size = b.style.point_size;
  open_virtual_cloud(main, render, b.options, style, b.cache, b.built, b.stats);
  progress.building = false;
  progress.switched = true;
  progress.frames_before = b.frames;
  progress.phase = 3;
  progress.fraction = 1;
  holder->build.reset();
}

}  // namespace

std::string describe_cache_progress(const VirtualCacheProgress& progress) {
  const char* phase = progress.phase <= 1 ? "reading and sorting" : "writing pointlets";
  if (progress.phase >= 3) phase = "opening";
  return fmt::format("{} {:.0f}% ({:.1f} s)", phase, progress.fraction * 100, progress.seconds);
}

void VirtualPointCloudPlugin::build(Engine& engine) {
  if (options.files.empty()) fail("VirtualPointCloudPlugin: no input");
  options.device_in_host = gpu::is_cpu_adapter(engine.render().resource<GpuContext>()->description);
  // A budget the process exceeds already fails before the cache is built (minutes, for a large
  // input); select_points checks again once the cache's tables are up.
  if (options.process_budget > 0)
    if (const uint64_t baseline = trimmed_resident_bytes(); baseline > 0)
      check_process_budget(options, baseline, kMinimumBudgetPoints, 0, "and the libraries");
  if (options.build_in_background &&
      !pointlet_cache_current(options.files, options.cache_dir, options.build)) {
    auto b = std::make_shared<BackgroundBuild>();
    b->options = options;
    b->style = render;
    b->options.build.progress = false;
    b->options.build.report = b->progress;
    // The thread holds the state by a plain pointer: the state's destructor joins it.
    b->thread = std::thread([state = b.get()] {
      try {
        state->cache = std::make_shared<const PointletCache>(
            open_pointlet_cache(state->options.files, state->options.cache_dir,
                                state->options.build, &state->built, &state->stats));
      } catch (...) {
        state->error = std::current_exception();
      }
      state->finished = true;
    });
    engine.main().insert_resource(VirtualBackgroundBuild{std::move(b)});
    VirtualCacheProgress progress;
    progress.building = true;
    engine.main().insert_resource(progress);
    // The sample's scene, under the input's name.
    if (auto* scene = engine.main().try_resource<SceneInfo>())
      scene->name = options.files.front().filename().string();
    engine.add_system(MainStage::Extract, activate_virtual_cloud, "activate_virtual_cloud");
  } else {
    bool built = false;
    PointletBuildStats build_stats;
    auto cache = std::make_shared<const PointletCache>(
        open_pointlet_cache(options.files, options.cache_dir, options.build, &built, &build_stats));
    open_virtual_cloud(engine.main(), engine.render(), options, render, std::move(cache), built,
                       build_stats);
  }
  engine.add_system(MainStage::Extract, extract_virtual_cloud, "extract_virtual_cloud");
  engine.add_system(RenderStage::Queue, queue_virtual_cloud, "queue_virtual_cloud");
}

}  // namespace stipple::pc
