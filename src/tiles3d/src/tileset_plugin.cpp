#include "stipple/tiles3d/tileset_plugin.hpp"

#include <algorithm>
#include <limits>
#include <optional>
#include <set>
#include <string_view>
#include <unordered_map>

#include "stipple/core/error.hpp"
#include "stipple/core/log.hpp"
#include "stipple/engine/camera.hpp"
#include "stipple/engine/engine.hpp"
#include "stipple/engine/render_plugins.hpp"
#include "stipple/engine/viewport.hpp"
#include "stipple/io/fetch.hpp"
#include "stipple/pointcloud/lod_batches.hpp"
#include "stipple/pointcloud/point_renderer.hpp"
#include "stipple/pointcloud/scene.hpp"
#include "stipple/tiles3d/render_load.hpp"
#include "stream_view.hpp"

namespace stipple::tiles3d {
namespace {

// Render-world resource, replaced in every Extract: what to draw this frame.
struct TilesetDrawList {
  std::vector<std::shared_ptr<const TileChunks>> draw;  // traversal order
  std::vector<uint32_t> resident;                       // sorted tile ids with chunks
  pc::CloudAttributes attributes;
};

// Render-world resource: GPU tiles and the per-frame drawn view.
struct TilesetGpu {
  struct Tile {
    std::shared_ptr<const TileChunks> data;  // keeps the CPU chunks as long as the GPU data
    pc::GpuPointCloud gpu;                   // chunks in page ranges (or dedicated buffers)
  };
  std::unordered_map<uint32_t, Tile> tiles;
  // The pass reads this cloud when the graph executes (Draw), so the drawn tiles' chunks are
  // moved into it in Queue and back in the next Prepare. Boxed: its address must not move.
  std::unique_ptr<pc::GpuPointCloud> drawn = std::make_unique<pc::GpuPointCloud>();
  std::vector<std::pair<uint32_t, uint32_t>> drawn_tiles;  // (tile, GPU chunks) in drawn order
  std::vector<std::pair<uint32_t, uint32_t>> last_drawn;
  uint32_t clod_capacity = 0;  // chunk slots of drawn->clod_args
  bool dirty = true;           // bind groups of the drawn view must be rebuilt
  std::unique_ptr<pc::PointPipelines> pipelines;
  WGPUTextureFormat format = WGPUTextureFormat_Undefined;
  uint64_t page_bytes = 0;
  std::unique_ptr<pc::PagedPoints> pages;  // created on first upload; null: dedicated buffers
};

// Render-world resource of the compute path: the tiles' LOD batches and the rasterizer.
struct TilesetComputeGpu {
  std::unique_ptr<pc::LodBatchStore> store;
  std::unique_ptr<pc::ComputeRasterPipeline> pipeline;
  WGPUTextureFormat format = WGPUTextureFormat_Undefined;
  uint64_t capacity = 0;  // point slots
  pc::ComputeRasterOptions raster;
  std::vector<uint64_t> keys;  // this frame's drawn tiles
};

}  // namespace

std::optional<pc::PickHit> pick_tileset_point(const TilesetStream& stream, const pc::PickRay& ray,
                                              const pc::PickFilter* filter) {
  std::optional<pc::PickHit> best;
  for (uint32_t t : stream.draw) {
    if (t >= stream.chunks.size() || !stream.chunks[t]) continue;
    for (const auto& chunk : stream.chunks[t]->chunks)
      pc::pick_in_chunk(chunk, chunk.bounds, ray, best, filter, false);
  }
  return best;
}

void fit_drawn_tiles(ViewFit& fit, const TilesetStream& stream) {
  std::vector<const pc::PointChunk*> chunks;
  for (uint32_t t : stream.draw)
    if (t < stream.chunks.size() && stream.chunks[t])
      for (const auto& chunk : stream.chunks[t]->chunks) chunks.push_back(&chunk);
  pc::fit_chunks(fit, chunks);
}

bool report_tile_problem(TilesetStream& stream, const TileError& problem) {
  if (stream.problems[std::string(tile_problem_kind(problem.message))]++ > 0) return false;
  STIPPLE_WARN("tile {}: {}", problem.tile, problem.message);
  if (stream.first_problem.empty()) stream.first_problem = problem.message;
  return true;
}

uint64_t unreported_tile_problems(const TilesetStream& stream) {
  uint64_t n = 0;
  for (const auto& [kind, count] : stream.problems) n += count - 1;
  return n;
}

namespace {

std::optional<pc::PickHit> pick_tileset(Registry& main, const pc::PickRay& ray) {
  const auto* stream = main.try_resource<TilesetStream>();
  return stream ? pick_tileset_point(*stream, ray, main.try_resource<pc::PickFilter>())
                : std::nullopt;
}

// MainStage::Update: one streamer update with the first camera.
void update_tileset(Registry& main) {
  auto& s = main.resource<TilesetStream>();
  auto& stats = main.resource<TilesetStats>();
  s.draw.clear();
  const std::optional<View> view = stream_view(main, s.width, s.height, s.world_from_tileset);
  if (!view) return;
  const Selection& selection = s.streamer->update(*view);
  for (const auto& e : s.streamer->take_errors()) {
    report_tile_problem(s, e);
    ++stats.errors;
  }
  for (const auto& w : s.streamer->take_warnings()) report_tile_problem(s, w);

  // Evicted (or failed) tiles disappear; loaded ones come with the chunks their worker made.
  const auto& states = s.streamer->states();
  if (s.chunks.size() < states.size()) s.chunks.resize(states.size());
  stats.resident_tiles = 0;
  stats.resident_points = 0;
  for (size_t t = 0; t < states.size(); ++t) {
    const PreparedTile* prepared = s.streamer->prepared(uint32_t(t));
    if (!prepared) {
      s.chunks[t].reset();
      continue;
    }
    if (s.chunks[t] != prepared->chunks) {
      s.chunks[t] = prepared->chunks;
      if (prepared->chunks->transparent_points > 0) {
        const auto& contents = s.tileset->tiles[t].contents;
        report_tile_problem(
            s, {uint32_t(t), fmt::format("{}: alpha 0: fully transparent points are not "
                                         "drawn (the others are blended by their alpha in the "
                                         "RGB colour mode)",
                                         contents.empty() ? std::string("?") : contents[0])});
      }
    }
    ++stats.resident_tiles;
    stats.resident_points += s.chunks[t]->points;
  }
  stats.drawn_tiles = 0;
  stats.drawn_points = 0;
  for (uint32_t t : selection.render) {
    if (t >= s.chunks.size() || !s.chunks[t] || s.chunks[t]->points == 0) continue;
    s.draw.push_back(t);
    ++stats.drawn_tiles;
    stats.drawn_points += s.chunks[t]->points;
  }
  const auto streamer_stats = s.streamer->stats();
  stats.resident_bytes = streamer_stats.resident_bytes;
  stats.peak_resident_bytes = streamer_stats.peak_resident_bytes;
  stats.loads_completed = streamer_stats.loads_completed;
  stats.evictions = streamer_stats.evictions;
  stats.discarded_over_budget = streamer_stats.discarded_over_budget;
  stats.budget_limited = streamer_stats.budget_limited;
  stats.sse_threshold = streamer_stats.sse_threshold;
  stats.idle = s.streamer->idle();
  stats.memory_budget = s.streamer->traversal_options().memory_budget;  // the panel may change it
  ++stats.frames;
  auto& info = main.resource<pc::SceneInfo>();
  info.points = std::max(info.points, stats.drawn_points);
  pc::CloudAttributes& scene = info.attributes;
  uint64_t signature = 0;
  for (uint32_t t : s.draw) {
    const pc::CloudAttributes& a = s.chunks[t]->attributes;
    scene.has_rgb = scene.has_rgb || a.has_rgb;
    scene.has_intensity = scene.has_intensity || a.has_intensity;
    scene.has_classification = scene.has_classification || a.has_classification;
    scene.has_returns = scene.has_returns || a.has_returns;
    scene.has_translucent = scene.has_translucent || a.has_translucent;
    if (a.has_intensity) signature = signature * 1000003u + t + 1;
  }
  // Intensity ramp: 2nd and 98th percentiles of the drawn tiles' samples, each weighted by the
  // points it stands for (as LAS input's ramp is over all its points); recomputed only when the
  // drawn set changes and only while intensities are shown (a moving view over thousands of
  // tiles changes the set every frame: sorting their samples each frame cost the browser page
  // ~30 ms a frame at 1,705 tiles). At most kRampSamples values are sorted: a tile's sample is
  // strided down, its weight scaled up, where the drawn tiles hold more.
  const auto& draw_settings = main.resource<pc::PointDrawSettings>().render;
  const bool shows_intensity =
      pc::resolve_color_mode(scene, draw_settings.color) == pc::ColorMode::Intensity;
  if (!shows_intensity) {
    s.intensity_signature = 0;  // computed afresh once intensities are shown
  } else if (signature != 0 && signature != s.intensity_signature) {
    // (A tile with intensities has a non-empty sample.)
    s.intensity_signature = signature;
    constexpr size_t kRampSamples = 65536;
    size_t total = 0;
    for (uint32_t t : s.draw) total += s.chunks[t]->intensity_sample.size();
    const size_t stride = std::max<size_t>(1, (total + kRampSamples - 1) / kRampSamples);
    std::vector<double> values, weights;
    values.reserve(total / stride + s.draw.size());
    weights.reserve(total / stride + s.draw.size());
    for (uint32_t t : s.draw) {
      const TileChunks& tile = *s.chunks[t];
      if (tile.intensity_sample.empty()) continue;
      const size_t n = tile.intensity_sample.size();
      const size_t taken = (n + stride - 1) / stride;
      const double w = double(tile.points) / double(taken);
      for (size_t i = 0; i < n; i += stride) {
        values.push_back(tile.intensity_sample[i]);
        weights.push_back(w);
      }
    }
    scene.intensity_percentiles =
        pc::percentile_range(std::move(values), std::move(weights), 0.02, 0.98);
  }
}

void extract_tileset(Registry& main) {
  Registry& render = *main.resource<RenderWorldRef>();
  render.insert_resource(main.resource<pc::PointDrawSettings>());
  const auto& s = main.resource<TilesetStream>();
  TilesetDrawList list;
  list.attributes = main.resource<pc::SceneInfo>().attributes;
  list.draw.reserve(s.draw.size());
  for (uint32_t t : s.draw) list.draw.push_back(s.chunks[t]);
  for (size_t t = 0; t < s.chunks.size(); ++t)
    if (s.chunks[t]) list.resident.push_back(uint32_t(t));
  render.insert_resource(std::move(list));
}

// Chunks moved into the drawn view last Queue go back to their tiles.
void return_drawn(TilesetGpu& g) {
  size_t next = 0;
  for (auto [tile, count] : g.drawn_tiles) {
    auto& chunks = g.tiles.at(tile).gpu.chunks;
    for (uint32_t i = 0; i < count; ++i) chunks[i] = std::move(g.drawn->chunks[next++]);
  }
  g.drawn->chunks.clear();
  g.drawn->point_count = 0;
  g.last_drawn = std::move(g.drawn_tiles);
  g.drawn_tiles.clear();
}

// Prepare, compute path: tiles the main world dropped leave the store, newly drawn ones enter.
void prepare_tileset_compute(Registry& render) {
  auto& c = render.resource<TilesetComputeGpu>();
  gpu::Context& ctx = *render.resource<GpuContext>();
  if (!c.store)
    c.store = std::make_unique<pc::LodBatchStore>(
        pc::create_lod_batch_store(ctx, c.capacity, c.capacity / 1024 + 256));
  pc::LodBatchStore& store = *c.store;
  pc::collect_lod_frees(ctx, store);
  auto& stats = render.resource<TilesetGpuStats>();
  const auto* list = render.try_resource<TilesetDrawList>();
  if (list) {
    std::vector<uint64_t> gone;
    for (const auto& [key, r] : store.resident)
      if (!std::binary_search(list->resident.begin(), list->resident.end(), uint32_t(key)))
        gone.push_back(key);
    for (uint64_t key : gone) {
      pc::release_lod_batches(store, key);
      ++stats.frees;
    }
    for (const auto& data : list->draw) {
      if (!data->batches || pc::has_lod_batches(store, data->tile, data->batches)) continue;
      if (pc::upload_lod_batches(ctx, store, data->tile, data->batches)) ++stats.uploads;
    }
  }
  stats.gpu_tiles = uint32_t(store.resident.size());
  stats.gpu_points = store.resident_points;
  // Five arrays of one word a slot; the slots in use include those waiting for their frame.
  const uint64_t slots_used = store.slots.capacity() - store.slots.free_bytes();
  stats.gpu_bytes = (slots_used > 0 ? 5 * pc::raster_array_bytes(slots_used) : 0) +
                    uint64_t(store.cloud.segments.front().batch_count) * pc::kGpuBatchBytes;
  stats.gpu_reserved_bytes =
      5 * pc::raster_array_bytes(store.capacity) + store.batch_capacity * pc::kGpuBatchBytes;
  stats.refused_uploads = store.refused;
}

void prepare_tileset(Registry& render) {
  if (render.try_resource<TilesetComputeGpu>()) {
    prepare_tileset_compute(render);
    return;
  }
  auto& g = render.resource<TilesetGpu>();
  return_drawn(g);
  gpu::Context& ctx = *render.resource<GpuContext>();
  auto& stats = render.resource<TilesetGpuStats>();
  if (g.pages) pc::collect_frees(ctx, *g.pages);
  const auto* list = render.try_resource<TilesetDrawList>();
  if (list) {
    // Free the GPU data of tiles the main world no longer holds (page ranges once the frames
    // that may read them are done).
    for (auto it = g.tiles.begin(); it != g.tiles.end();) {
      if (!std::binary_search(list->resident.begin(), list->resident.end(), it->first)) {
        if (g.pages) pc::free_chunks_deferred(*g.pages, it->second.gpu.chunks);
        it = g.tiles.erase(it);
        ++stats.frees;
        g.dirty = true;
      } else {
        ++it;
      }
    }
    bool uploaded = false;
    for (const auto& data : list->draw) {
      auto& tile = g.tiles[data->tile];
      if (tile.data == data) continue;
      if (g.page_bytes > 0 && !g.pages)
        g.pages = std::make_unique<pc::PagedPoints>(pc::create_paged_points(ctx, g.page_bytes));
      // A tile reloaded under the same id: its old data goes first.
      if (g.pages) pc::free_chunks_deferred(*g.pages, tile.gpu.chunks);
      tile.data = data;
      tile.gpu = {};
      for (const auto& chunk : data->chunks) {
        if (chunk.vertices.empty()) continue;
        if (g.pages)
          pc::upload_chunk_paged(ctx, *g.pages, tile.gpu, chunk);
        else
          pc::upload_chunk(ctx, tile.gpu, chunk);
      }
      ++stats.uploads;
      uploaded = true;
      g.dirty = true;
    }
    if (uploaded) ctx.check("uploading tiles");
  }
  stats.gpu_tiles = uint32_t(g.tiles.size());
  stats.gpu_points = 0;
  for (const auto& [id, tile] : g.tiles) stats.gpu_points += tile.gpu.point_count;
  stats.paged = g.page_bytes > 0;
  if (g.pages) {
    stats.pages = *g.pages->stats;
    stats.allocator = g.pages->allocator->stats();
    stats.pending_frees = g.pages->pending.size();
    stats.gpu_bytes = stats.allocator.bytes_used;
    stats.gpu_reserved_bytes = stats.allocator.bytes_reserved;
  } else {
    uint64_t bytes = 0;
    for (const auto& [id, tile] : g.tiles)
      for (const auto& chunk : tile.gpu.chunks)
        for (WGPUBuffer b : {chunk.points.get(), chunk.survivors.get(), chunk.extras.get()})
          if (b) bytes += wgpuBufferGetSize(b);
    stats.gpu_bytes = stats.gpu_reserved_bytes = bytes;
  }
}

// PostDraw: the frame's work is submitted; ranges freed from now on wait for it.
void mark_tileset_frame(Registry& render) {
  if (auto* c = render.try_resource<TilesetComputeGpu>()) {
    if (c->store && render.resource<FrameGraph>().executed)
      pc::mark_lod_frame_submitted(*render.resource<GpuContext>(), *c->store);
    return;
  }
  auto& g = render.resource<TilesetGpu>();
  if (g.pages && render.resource<FrameGraph>().executed)
    pc::mark_frame_submitted(*render.resource<GpuContext>(), *g.pages);
}

void queue_tileset(Registry& render) {
  auto& fg = render.resource<FrameGraph>();
  if (!fg.active) return;
  const auto* list = render.try_resource<TilesetDrawList>();
  if (!list) return;
  const auto& target = render.resource<RenderTarget>();
  const ExtractedCamera* extracted = first_extracted_camera(render);
  if (!extracted) return;
  const auto& settings = render.resource<pc::PointDrawSettings>();
  gpu::Context& ctx = *render.resource<GpuContext>();
  if (auto* c = render.try_resource<TilesetComputeGpu>()) {
    if (!c->pipeline || c->format != target.format) {
      c->pipeline = std::make_unique<pc::ComputeRasterPipeline>(
          pc::create_compute_raster_pipeline(ctx, target.format));
      c->format = target.format;
    }
    c->keys.clear();
    for (const auto& data : list->draw) c->keys.push_back(data->tile);
    pc::GpuBatchedCloud& drawn = pc::select_lod_batches(ctx, *c->store, c->keys);
    pc::ComputeRasterOptions options = c->raster;
    options.background = settings.render.background;
    options.sky = settings.render.sky;
    options.edl_strength = settings.render.edl ? settings.render.edl_strength : 0.0f;
    options.edl_radius = settings.render.edl_radius;
    options.point_size = pc::compute_point_size(settings.render);
    options.storage_target = (target.usage & WGPUTextureUsage_StorageBinding) != 0;
    // The billboard path's colours: ramps over the root volume and the drawn tiles' intensities.
    options.shading = pc::point_shading(settings.render, list->attributes);
    options.shading.mode = pc::resolve_color_mode(list->attributes, options.shading.mode);
    options.translucent = pc::translucent_frame(list->attributes, options.shading);
    options.filter = settings.render.filter;
    options.clip = settings.render.clip;
    options.highlight = settings.render.highlight;
    options.depth_texture = "depth";  // later passes (splats) test against it
    pc::add_compute_raster_passes(fg.graph, *c->pipeline, drawn, to_camera(*extracted), options,
                                  target.width, target.height);
    auto& stats = render.resource<RenderStats>();
    stats.points_total = c->store->resident_points;
    stats.points_drawn += drawn.point_count;
    return;
  }
  auto& g = render.resource<TilesetGpu>();
  if (!g.pipelines || g.format != target.format) {
    g.pipelines =
        std::make_unique<pc::PointPipelines>(pc::create_point_pipelines(ctx, target.format));
    g.format = target.format;
    g.dirty = true;
  }
  // The drawn view: the selected tiles' chunks, in traversal order.
  pc::GpuPointCloud& drawn = *g.drawn;
  for (const auto& data : list->draw) {
    auto& tile = g.tiles.at(data->tile);
    uint32_t count = uint32_t(tile.gpu.chunks.size());
    for (auto& chunk : tile.gpu.chunks) {
      drawn.point_count += chunk.count;
      drawn.chunks.push_back(std::move(chunk));
    }
    g.drawn_tiles.emplace_back(data->tile, count);
  }
  // Its own CLOD argument slots, one per chunk: grown to the largest chunk count seen.
  if (drawn.chunks.size() > g.clod_capacity || !drawn.clod_args) {
    g.clod_capacity = std::max<uint32_t>(64, uint32_t(drawn.chunks.size()) * 2);
    drawn.clod_args_stride = std::max<uint32_t>(256, ctx.limits.minStorageBufferOffsetAlignment);
    drawn.clod_args = gpu::create_buffer(ctx, uint64_t(g.clod_capacity) * drawn.clod_args_stride,
                                         WGPUBufferUsage_Storage | WGPUBufferUsage_Indirect |
                                             WGPUBufferUsage_CopyDst | WGPUBufferUsage_CopySrc,
                                         "clod-args-tiles");
    g.dirty = true;
  }
  // Bind groups name the chunk's CLOD slot: rebuilt when the drawn list changes.
  if (g.dirty || g.drawn_tiles != g.last_drawn) drawn.bind_groups_for = nullptr;
  g.dirty = false;
  drawn.attributes = list->attributes;
  auto& stats = render.resource<RenderStats>();
  stats.points_total = render.resource<TilesetGpuStats>().gpu_points;
  if (drawn.chunks.empty() && !settings.render.sky.enabled) {
    // Nothing resident (yet), or nothing in view: the frame is the background. (With the sky
    // the point passes run over no chunks: their resolve draws the sky.)
    const glm::vec3 bg = settings.render.background;
    fg.graph
        .add_pass("clear", gpu::PassKind::Render,
                  [bg](gpu::PassContext& pc) {
                    WGPURenderPassColorAttachment color = WGPU_RENDER_PASS_COLOR_ATTACHMENT_INIT;
                    color.view = pc.view("color");
                    color.loadOp = WGPULoadOp_Clear;
                    color.storeOp = WGPUStoreOp_Store;
                    color.clearValue = {bg.r, bg.g, bg.b, 1.0};
                    WGPURenderPassDescriptor desc = WGPU_RENDER_PASS_DESCRIPTOR_INIT;
                    desc.colorAttachmentCount = 1;
                    desc.colorAttachments = &color;
                    gpu::RenderPassEncoder pass = pc.begin_render_pass(desc);
                    wgpuRenderPassEncoderEnd(pass.get());
                  })
        .write("color");
    return;
  }
  Camera camera = to_camera(*extracted);
  // The depth stays stored for later passes of the frame (splats test against it).
  pc::PointPassTargets targets;
  targets.keep_depth = true;
  pc::add_point_cloud_passes(fg.graph, *g.pipelines, drawn, camera, settings.render, target.width,
                             target.height, targets);
  stats.points_drawn += drawn.point_count;
}

}  // namespace

void TilesetPlugin::build(Engine& engine) {
  Registry& main = engine.main();
  io::TilesetOptions ts_options = streamer.tileset;
  ts_options.fetch = streamer.fetch;
  TilesetStream s;
  std::set<std::string> not_drawn;
  const io::Fetcher fetcher = [&ts_options](const std::string& u) {
    return io::fetch(u, ts_options.fetch);
  };
  auto tileset = std::make_shared<io::Tileset>(
      io::load_tileset(uri, format ? *format : io::source_format(uri), fetcher, ts_options));
  s.tileset = tileset;
  for (const auto& w : s.tileset->warnings) report_tile_problem(s, {0, w});
  for (const auto& e : s.tileset->errors) report_tile_problem(s, {0, e});
  if (s.tileset->tiles.empty()) fail("{}: the tileset has no tiles", uri);
  s.world_from_tileset = world_from_tileset(*s.tileset);
  {
    // Framed on the point content where the tileset holds other content too (warned once).
    std::string warning;
    s.world_bounds = drawable_world_bounds(
        *s.tileset, s.world_from_tileset,
        [&](const std::string& u) { return io::fetch(u, streamer.fetch); }, &warning, &not_drawn);
    if (!warning.empty()) STIPPLE_WARN("{}", warning);
  }
  s.width = width;
  s.height = height;
  // Workers convert each decoded tile to world-space chunks and drop the decoded form.
  StreamerOptions options = streamer;
  options.not_drawn_warned = not_drawn;
  // Those kinds are not warned about again by tile: they are the reason if nothing is drawn.
  if (!not_drawn.empty()) {
    std::string kinds;
    for (const auto& k : not_drawn) kinds += (kinds.empty() ? "" : ", ") + k;
    s.first_problem =
        fmt::format("content is {}, which stipple does not draw (points only)", kinds);
  }
  // On the compute path the workers also make each tile's LOD batches (coloured per frame).
  options.prepare = [world = s.world_from_tileset, batches = compute](
                        uint32_t tile, const glm::dmat4& transform,
                        std::vector<io::PointContent>& contents) {
    auto chunks = make_tile_chunks(tile, transform, world, contents, batches);
    std::vector<io::PointContent>().swap(contents);
    const uint64_t bytes = chunks->memory_bytes();
    return PreparedTile{std::move(chunks), bytes};
  };
  s.streamer = std::make_shared<TileStreamer>(tileset, std::move(options));
  s.chunks.resize(s.tileset->tiles.size());

  pc::SceneInfo info;
  info.world_bounds = s.world_bounds;
  info.name = uri.substr(uri.find_last_of("/\\") + 1);
  if (info.name.empty()) info.name = uri;
  // Elevation ramp over the root volume (the data arrives later).
  info.attributes.elevation_percentiles = {s.world_bounds.min.y, s.world_bounds.max.y};
  TilesetStats stats;
  stats.memory_budget = streamer.traversal.memory_budget;
  STIPPLE_INFO("{}: {} tiles, streaming (budget {:.1f} MiB)", uri, s.tileset->tiles.size(),
               double(streamer.traversal.memory_budget) / (1 << 20));
  main.insert_resource(std::move(info));
  main.insert_resource(std::move(s));
  main.insert_resource(stats);
  pc::PointDrawSettings settings;
  settings.render = render;
  settings.budget = budget;
  main.insert_resource(settings);
  engine.render().insert_resource(settings);
  TilesetGpu g;
  g.page_bytes = gpu_page_bytes;
  engine.render().insert_resource(std::move(g));
  if (compute) {
    TilesetComputeGpu c;
    // Every resident tile fits: each holds at least 40 bytes a point on the host (20 in its
    // chunks, 20 in its batches); a quarter more leaves room for the free list's gaps.
    c.capacity = streamer.traversal.memory_budget / 40 * 5 / 4;
    c.raster = raster;
    engine.render().insert_resource(std::move(c));
  }
  engine.render().insert_resource(TilesetGpuStats{});

  pc::add_scene_picker(main, pick_tileset);

  engine.add_system(MainStage::Update, update_tileset, "update_tileset");
  engine.add_system(MainStage::Extract, extract_tileset, "extract_tileset");
  engine.add_system(RenderStage::Prepare, prepare_tileset, "prepare_tileset");
  engine.add_system(RenderStage::Queue, queue_tileset, "queue_tileset");
  engine.add_system(RenderStage::PostDraw, mark_tileset_frame, "mark_tileset_frame");
}

}  // namespace stipple::tiles3d
