#pragma once
// The GPU side of the virtual memory system (seed 002, III-C): the points a frame draws, in
// buffers sized by the point bucket and kept for two consecutive frames. When the selection
// changes, plan_compaction (CPU) compares what each pointlet drew in the previous frame with
// what it draws now and writes the compaction info: which range to keep from the previous
// buffers, where it goes, and which new points follow it. The new points go through a mapped
// staging buffer (bounded: what does not fit follows in later frames, spread over every
// pointlet), and a compute pass (shaders/vms_compact.wgsl) rebuilds the other pair of buffers
// from the kept and the new points; the frame then draws it with the compute rasterizer, one
// batch (or more) per pointlet, quantized relative to the pointlet's box.
//
// A pointlet's points are shuffled in the cache, so what it draws is always a prefix: the
// compaction keeps min(before, now) points and adds the rest after them.
#include <cstdint>
#include <functional>
#include <span>
#include <string>
#include <vector>

#include "stipple/math/aabb.hpp"
#include "stipple/pointcloud/batches.hpp"
#include "stipple/pointcloud/compute_raster.hpp"
#include "stipple/pointcloud/pointlets.hpp"
#include "stipple/renderer/gpu.hpp"
#include "stipple/renderer/render_graph.hpp"
#include "stipple/renderer/staging.hpp"

namespace stipple::pc {

// Where each pointlet's drawn prefix lives in one frame's buffers: pointlets in index order,
// each contiguous.
struct StoreLayout {
  std::vector<uint32_t> first, count;  // per pointlet (first is valid where count > 0)
  uint64_t total = 0;
};

// One range of the compaction info (16 bytes, as the shader reads it).
struct CompactionJob {
  uint32_t dst = 0, src = 0, count = 0;
  uint32_t fresh = 0;  // 1: src indexes the new points, 0: the previous frame's buffers
};
// New points of one pointlet: its records [first, first + count), written at new point `at`.
struct FreshRange {
  uint32_t pointlet = 0, first = 0, count = 0;
  uint32_t at = 0;
};
struct CompactionPlan {
  StoreLayout next;
  std::vector<CompactionJob> jobs;  // sorted by dst, covering [0, next.total)
  std::vector<FreshRange> fresh;
  uint64_t kept = 0, fresh_points = 0;
  bool limited = false;  // fewer new points than asked for: the rest follow later
  bool changed = false;  // some pointlet draws another count than before (or none was before)
};
// `wanted`: the points each pointlet should draw now (already capped by what the host holds);
// at most `max_fresh` new points, shared among the pointlets in proportion to what they lack.
// With a pool, pieces of pointlets are counted and then placed on its threads; the plan is the
// same either way (jobs merge within a piece of 8,192 pointlets, not across).
CompactionPlan plan_compaction(const StoreLayout& previous, const std::vector<uint32_t>& wanted,
                               uint64_t max_fresh, ThreadPool* pool = nullptr);
// The same into `plan`, reusing its vectors.
void plan_compaction(const StoreLayout& previous, const std::vector<uint32_t>& wanted,
                     uint64_t max_fresh, CompactionPlan& plan, ThreadPool* pool = nullptr);

struct GpuPointStore {
  uint64_t capacity = 0;  // points per frame's buffers (>= B)
  uint32_t pointlets = 0;
  std::vector<Aabb> boxes;  // per pointlet, world space (Y up): the batches' boxes
  GpuBatchedCloud slabs[2];
  uint32_t current = 0;  // the buffers the frame draws
  StoreLayout layout;    // of slabs[current]
  CompactionPlan plan;   // the last update's (its vectors are reused)
  gpu::Buffer fresh, jobs, params;
  uint64_t fresh_capacity = 0, jobs_capacity = 0;  // points, jobs
  gpu::StagingRing staging;
  gpu::ComputePipeline positions, colors;  // colors: the colour and attribute words
  uint64_t gpu_bytes = 0;                  // every buffer above (device memory)
  bool cleared = false;  // the buffers were written once (the first vms-compact pass)
  // Set by update_point_store, recorded by the vms-compact pass.
  struct Pending {
    bool active = false;
    gpu::StagingWrite write;
    uint64_t job_count = 0, fresh_points = 0, fresh_offset = 0;
    uint32_t from = 0;
    uint64_t jobs_at = 0;  // u32s of per-workgroup first jobs before the jobs
    uint64_t total = 0;    // points the compacted buffers hold
  } pending;
};

// Buffers for `capacity` points per frame over `boxes.size()` pointlets; new points travel
// through `staging_slots` (at least two) staging slots of `staging_bytes` each (which must also
// hold the compaction info).
GpuPointStore create_point_store(gpu::Context& ctx, uint64_t capacity, std::vector<Aabb> boxes,
                                 uint64_t staging_bytes, uint32_t staging_slots = 2);
// The most new points one update can bring.
uint64_t max_fresh_points(const GpuPointStore& store);

// Words a point takes in the store's arrays and in staging: coarse, medium, fine (its position
// quantized in the pointlet's world box), RGBA, and the attribute word.
inline constexpr uint32_t kStoreWords = 5;

// The cache's pointlet boxes in world space (Y up).
std::vector<Aabb> pointlet_world_boxes(const PointletCache& cache);
// The kStoreWords words of each of `records` (one pointlet's), written at `words`.
void pointlet_words(const PointletCache& cache, const PointletEntry& pointlet,
                    const Aabb& world_box, std::span<const PointletRecord> records,
                    uint32_t* words);

// Writes the new points of `ranges` as kStoreWords words each at `words` (range r at words +
// kStoreWords * r.at); called once per update, free to work in parallel.
using FreshWriter = std::function<void(std::span<const FreshRange> ranges, uint32_t* words)>;

struct StoreUpdate {
  bool changed = false;  // a compaction was planned (the next graph must carry the pass)
  uint64_t kept = 0, fresh = 0;
  bool limited = false;
  std::vector<uint32_t> drawn;       // per pointlet, what the frame draws
  double wait_ms = 0, write_ms = 0;  // CPU: waiting for a staging slot, writing new points
  GpuPointStore::Pending pending;    // what the vms-compact pass records (when changed)
};
// Plans the next frame's buffers for `wanted` (<= capacity in total; what each pointlet then
// draws is store.layout.count) and writes the new points
// into staging; the compaction runs in the vms-compact pass. Call it at most once per frame,
// after the previous frame's graph was submitted. The plan, its info in staging and the batches
// are made on `pool`'s threads too when one is given (the same result).
StoreUpdate update_point_store(gpu::Context& ctx, GpuPointStore& store,
                               const std::vector<uint32_t>& wanted, const FreshWriter& write,
                               ThreadPool* pool = nullptr);
// The same in two steps, so that the CPU work can run on another thread while frames draw the
// current buffers: prepare plans and writes into `w` (a slot the caller mapped on the device's
// thread: gpu::staging_submitted, then gpu::begin_staging_write) and into the buffers the
// frames do not draw; commit, on the frame's thread between frames, makes a changed update the
// next graph's (its vms-compact pass) and the buffers it fills the drawn ones. One update at a
// time: the next is prepared after the last was committed.
StoreUpdate prepare_point_store_update(GpuPointStore& store, const std::vector<uint32_t>& wanted,
                                       const FreshWriter& write, const gpu::StagingWrite& w,
                                       ThreadPool* pool = nullptr);
void commit_point_store_update(GpuPointStore& store, const StoreUpdate& update);
// The vms-compact pass (a side effect: the rasterizer reads the store's buffers directly). Add
// it before the rasterizer's passes; the store must outlive the graph's run.
void add_point_store_pass(gpu::RenderGraph& graph, GpuPointStore& store);
// What the rasterizer draws this frame.
inline GpuBatchedCloud& drawn_points(GpuPointStore& store) {
  return store.slabs[store.current];
}

}  // namespace stipple::pc
