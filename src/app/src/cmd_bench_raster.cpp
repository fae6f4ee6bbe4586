// `stipple bench raster`: the compute rasterizer against the billboard path on the built-in
// scene (seed 001, Tables 1-2). For each size N the scene is generated (deterministic, in
// parallel, quantized per batch while generating), uploaded once, and every variant renders the
// same views: GPU ms per frame from timestamp queries (sum of the frame's passes, median over
// frames), points per second, batch counters, and the bytes of point data loaded per second
// against a measured buffer-to-buffer copy bandwidth.
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <fstream>
#include <functional>
#include <map>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "bench_bandwidth.hpp"
#include "stipple/app/commands.hpp"
#include "stipple/core/atomic_file.hpp"
#include "stipple/core/error.hpp"
#include "stipple/core/stats.hpp"
#include "stipple/core/thread_pool.hpp"
#include "stipple/io/procedural.hpp"
#include "stipple/math/camera.hpp"
#include "stipple/pointcloud/batches.hpp"
#include "stipple/pointcloud/compute_raster.hpp"
#include "stipple/pointcloud/point_renderer.hpp"
#include "stipple/renderer/gpu.hpp"
#include "stipple/renderer/gpu_timer.hpp"
#include "stipple/renderer/render_graph.hpp"

namespace stipple::app {
namespace {

using Clock = std::chrono::steady_clock;

struct RasterArgs {
  std::vector<uint64_t> points = {100'000'000};
  uint32_t width = 2560, height = 1140;
  uint32_t frames = 10, warmup = 3;
  std::string backend;
  std::string order = "morton";
  std::string json;
  uint32_t copy_mb = 2048;
  std::vector<std::string> variants;  // empty: all but the measurements (ablations)
  bool billboard = true;
  uint32_t seed = 1;
};

// Billboard vertices decoded from the same quantized points, one chunk per ~1M points.
pc::GpuPointCloud upload_billboards(gpu::Context& ctx, const pc::BatchedCloud& cloud,
                                    ThreadPool& pool) {
  pc::GpuPointCloud out;
  std::vector<pc::PointChunk::Vertex> vertices;
  size_t b = 0;
  while (b < cloud.batches.size()) {
    size_t e = b;
    uint64_t count = 0;
    while (e < cloud.batches.size() && count < (1u << 20)) count += cloud.batches[e++].count;
    glm::dvec3 origin = cloud.batches[b].min;
    uint64_t base = cloud.batches[b].first;
    vertices.resize(count);
    pool.parallel_for(e - b, 8, [&](size_t lo, size_t hi) {
      for (size_t k = b + lo; k < b + hi; ++k) {
        const pc::Batch& batch = cloud.batches[k];
        for (uint64_t i = batch.first; i < batch.first + batch.count; ++i) {
          glm::dvec3 p = pc::dequantize({cloud.coarse[i], cloud.medium[i], cloud.fine[i]}, 30,
                                        batch.min, batch.size) -
                         origin;
          vertices[i - base] = {float(p.x), float(p.y), float(p.z), cloud.color[i], 0u};
        }
      }
    });
    pc::PointChunk chunk;
    chunk.origin = origin;
    chunk.vertices = std::move(vertices);
    pc::upload_chunk(ctx, out, chunk);
    vertices = std::move(chunk.vertices);
    if (out.chunks.size() % 256 == 0) ctx.wait_idle();  // bound the staging memory
    b = e;
  }
  pc::finish_upload(ctx, out);
  out.attributes.has_rgb = true;
  ctx.wait_idle();
  ctx.check("uploading billboards");
  return out;
}

struct View {
  std::string name;
  Camera camera;
};

std::vector<View> bench_views(const Aabb& world, double aspect) {
  std::vector<View> views;
  views.push_back({"overview", frame_box(world, aspect, 30.0, 40.0, 50.0)});
  // Low over the town looking across it: most batches behind or beside the camera, the rest
  // spanning near (large, precise) to far (tiny).
  glm::dvec3 c = y_up_to_z_up(world.center()), s = y_up_to_z_up(world.size());
  double span = std::max(std::abs(s.x), std::abs(s.y));
  Camera close;
  close.fov_y = glm::radians(60.0);
  close.look_at(z_up_to_y_up({c.x - span * 0.05, c.y - span * 0.05, c.z + 20.0}),
                z_up_to_y_up({c.x + span * 0.2, c.y + span * 0.1, c.z - 30.0}));
  close.near_plane = 0.5;
  views.push_back({"closeup", close});
  return views;
}

void run_raster_bench(const RasterArgs& args) {
  gpu::ContextOptions options;
  options.backend = args.backend;
  options.optional_features = pc::compute_raster_features();
  auto ctx = gpu::create_context(options);
  if (!ctx->has_feature(WGPUFeatureName_TimestampQuery))
    fail("bench raster needs timestamp queries, which this adapter lacks");
  const bool has64 = pc::has_visibility64(*ctx);
  std::printf("%s on %s (%s): %s\n", ctx->description.backend.c_str(),
              ctx->description.device.c_str(), ctx->description.graphics_api.c_str(),
              has64 ? "64-bit visibility buffer" : "no 64-bit atomics: 32-bit two-pass fallback");
  // The variants: what the rasterizer draws (the seed's basic and adaptive-precision kernels,
  // HQS, the 32-bit fallback, larger points) and the billboard path, each its own pipeline;
  // "compute-precision" is the default. The variants that measured slower are retired
  // (bench/RESULTS.md, "Retired rasterizer variants"). Parsed before any scene is generated, so
  // that a wrong name fails at once.
  struct Variant {
    std::string name;
    pc::RasterKernel kernel;
    bool fallback = false;
    pc::ComputeRasterOptions options;
    bool billboard = false;
  };
  // Each name changes one thing of the default; "a+b" applies both (e.g. compute-hqs+no-sums).
  std::vector<std::pair<std::string, std::function<void(Variant&)>>> changes;
  auto add = [&](std::string name, std::function<void(Variant&)> change) {
    changes.emplace_back(std::move(name), std::move(change));
  };
  add("compute-basic", [](Variant& v) { v.options.force_bits = 30; });
  add("compute-precision", [](Variant&) {});
  add("compute-hqs", [](Variant& v) { v.options.hqs = true; });
  add("compute-fallback32", [](Variant& v) { v.fallback = true; });
  add("dilate-3px", [](Variant& v) { v.options.point_size = 3.0f; });
  if (args.billboard) add("billboard-1px", [](Variant& v) { v.billboard = true; });
  const size_t drawn = changes.size();  // run by default; the ablations below only when named
  // Where the time goes (RasterKernel::ablate; wrong images): parts of the batch passes left
  // out, combined with a variant (e.g. compute-precision+no-write).
  const std::pair<const char*, uint32_t> ablations[] = {
      {"no-atomic", pc::kAblateAtomic}, {"no-write", pc::kAblateWrite},
      {"no-early", pc::kAblateEarly},   {"no-load", pc::kAblateLoad},
      {"no-sums", pc::kAblateSums},     {"no-count", pc::kAblateCount}};
  for (const auto& ablation : ablations)
    add(ablation.first, [bit = ablation.second](Variant& v) { v.kernel.ablate |= bit; });
  std::vector<std::string> specs = args.variants;
  if (specs.empty())
    for (size_t i = 0; i < drawn; ++i) specs.push_back(changes[i].first);
  std::vector<Variant> variants;
  for (const std::string& spec : specs) {
    Variant v;
    v.name = spec;
    v.options.storage_target = true;  // compute display
    size_t from = 0;
    while (from <= spec.size()) {
      const size_t plus = std::min(spec.find('+', from), spec.size());
      const std::string part = spec.substr(from, plus - from);
      auto it = std::find_if(changes.begin(), changes.end(),
                             [&](const auto& c) { return c.first == part; });
      if (it == changes.end())
        fail("bench raster: unknown variant '{}' in '{}' (see --help)", part, spec);
      it->second(v);
      from = plus + 1;
    }
    if (v.fallback && !has64) continue;  // the plain pipeline is the fallback already
    variants.push_back(std::move(v));
  }
  // The bound: what a shader reaches reading memory (bench bandwidth); the copy for reference.
  const ReadBandwidth read = read_bandwidth(*ctx, uint64_t(args.copy_mb) << 20);
  const double read_gbs = read.gb_per_s;
  double copy_gbs = copy_bandwidth_gbs(*ctx, uint64_t(args.copy_mb) << 20);
  std::printf("read kernel: %.1f GB/s (the bound below); buffer copy: %.1f GB/s copied\n", read_gbs,
              copy_gbs);

  nlohmann::json out;
  out["backend"] = ctx->description.backend;
  out["adapter"] = ctx->description.device;
  out["width"] = args.width;
  out["height"] = args.height;
  out["frames"] = args.frames;
  out["visibility64"] = has64;
  out["copy_gb_per_s"] = copy_gbs;
  out["read_gb_per_s"] = read_gbs;
  out["runs"] = nlohmann::json::array();

  const WGPUTextureFormat format = WGPUTextureFormat_RGBA8Unorm;
  const WGPUTextureUsage usage =
      WGPUTextureUsage_RenderAttachment | WGPUTextureUsage_StorageBinding;
  gpu::Texture color =
      gpu::create_texture_2d(*ctx, args.width, args.height, format, usage, "bench-color");
  gpu::TextureView view = gpu::create_view(color);
  ThreadPool pool;

  std::printf("\n%-6s %-9s %-17s %9s %9s %9s %8s %15s %13s %19s %6s %7s %5s\n", "Mpts", "view",
              "variant", "frame ms", "geom ms", "acc ms", "Gpts/s", "batches pr/rend",
              "pts rendered", "batches 10/20/30b", "B/pt", "GB/s", "%bound");
  for (uint64_t n : args.points) {
    io::SceneParams scene;
    scene.point_count = n;
    scene.seed = args.seed;
    auto t0 = Clock::now();
    pc::BatchedCloud cloud = pc::generate_batched_scene(scene, pc::parse_spatial_order(args.order),
                                                        pc::kBatchPoints, true);
    double gen_s = std::chrono::duration<double>(Clock::now() - t0).count();
    t0 = Clock::now();
    pc::GpuBatchedCloud raster_cloud = pc::upload_batched_cloud(*ctx, cloud);
    double upload_s = std::chrono::duration<double>(Clock::now() - t0).count();
    std::printf(
        "# %llu points: generated in %.1f s, %zu batches, %zu segments, %.2f GB on the "
        "GPU (uploaded in %.1f s)\n",
        static_cast<unsigned long long>(n), gen_s, cloud.batches.size(),
        raster_cloud.segments.size(), double(raster_cloud.bytes) * 1e-9, upload_s);
    pc::GpuPointCloud billboards;
    if (args.billboard) billboards = upload_billboards(*ctx, cloud, pool);

    auto point_pipelines = pc::create_point_pipelines(*ctx, format);

    std::vector<std::unique_ptr<pc::ComputeRasterPipeline>> pipelines;
    for (const Variant& v : variants)
      pipelines.push_back(
          v.billboard
              ? nullptr
              : std::make_unique<pc::ComputeRasterPipeline>(pc::create_compute_raster_pipeline(
                    *ctx, format, v.fallback, pc::DisplayPass::Auto, v.kernel)));

    // The first variant of a run was 1.5-5x slower than the same variant later on the H200
    // (clocks and first touches of the freshly uploaded points): it warms up for longer.
    bool warmed = false;
    for (const View& v : bench_views(cloud.world_bounds, double(args.width) / args.height)) {
      for (size_t vi = 0; vi < variants.size(); ++vi) {
        const Variant& variant = variants[vi];
        const uint32_t warmup = warmed ? args.warmup : std::max(args.warmup, 50u);
        warmed = true;
        pc::ComputeRasterPipeline* pipeline = pipelines[vi].get();
        gpu::TransientPool transients;
        gpu::PassTimer timer;
        std::vector<double> frame_ms, geom_ms;
        std::map<std::string, std::vector<double>> pass_ms;  // each pass's time, per frame
        // 1-pixel depth-tested points, the billboard path's cheapest configuration.
        pc::PointRenderSettings style;
        style.point_size = 1.0f;
        style.round = false;
        style.splat = pc::SplatMode::Naive;
        style.edl = false;
        style.color = pc::ColorMode::Rgb;
        for (uint32_t f = 0; f < warmup + args.frames; ++f) {
          gpu::RenderGraph graph;
          graph.import_texture("color", color.get(), view.get(),
                               {args.width, args.height, format, usage}, gpu::Access::Writable);
          if (pipeline)
            pc::add_compute_raster_passes(graph, *pipeline, raster_cloud, v.camera, variant.options,
                                          args.width, args.height);
          else
            pc::add_point_cloud_passes(graph, point_pipelines, billboards, v.camera, style,
                                       args.width, args.height);
          graph.compile();
          if (f == 0) timer = gpu::create_pass_timer(*ctx, graph.plan().timed_passes);
          graph.execute(*ctx, transients, &timer);
          auto times = graph.read_pass_times(*ctx, timer);
          if (f < warmup) continue;
          double total = 0;
          for (const auto& [name, ms] : times) {
            total += ms;
            pass_ms[name].push_back(ms);
          }
          frame_ms.push_back(total);
          geom_ms.push_back(times.count("raster-depth") ? times["raster-depth"] : times["points"]);
        }
        ctx->check("bench frame");
        double ms = median(frame_ms), geom = median(geom_ms);
        nlohmann::json run;
        run["points"] = n;
        run["view"] = v.name;
        run["variant"] = variant.name;
        run["frame_gpu_ms"] = ms;
        run["geometry_gpu_ms"] = geom;
        run["frame_gpu_ms_all"] = frame_ms;
        run["pass_gpu_ms"] = nlohmann::json::object();  // medians: where a variant's time goes
        for (auto& [name, ms] : pass_ms) run["pass_gpu_ms"][name] = median(ms);
        run["points_per_second"] = ms > 0 ? double(n) / (ms * 1e-3) : 0.0;
        run["generate_s"] = gen_s;
        char batches[32] = "-", rendered[32] = "-", bits[40] = "-", bpp[16] = "-", gbs[16] = "-",
             pct[16] = "-";
        if (pipeline) {
          pc::RasterCounters c = pc::read_raster_counters(*ctx, *pipeline);
          // Bytes of point data the passes load: coordinate words by precision in the geometry
          // pass; the accumulation pass (HQS, fallback) loads them again plus a colour each.
          // The resolve reads one colour per pixel (negligible).
          double coords = 4.0 * double(c.points_by_bits[0]) + 8.0 * double(c.points_by_bits[1]) +
                          12.0 * double(c.points_by_bits[2]);
          // The fallback's winner events stand in for its second pass unless they overflowed.
          const bool events_ran = !variant.options.hqs && !pipeline->visibility64 &&
                                  pipeline->kernel.fallback_events == pc::AutoSwitch::On &&
                                  !c.events_overflowed;
          bool second = variant.options.hqs || (!pipeline->visibility64 && !events_ran);
          double loaded = coords + (second ? coords + 4.0 * double(c.points_rendered) : 0.0);
          double per_point = c.points_rendered ? loaded / double(c.points_rendered) : 0.0;
          double rate = ms > 0 ? loaded / (ms * 1e-3) * 1e-9 : 0.0;
          std::snprintf(batches, sizeof batches, "%u/%u", c.batches_processed, c.batches_rendered);
          std::snprintf(rendered, sizeof rendered, "%.1fM", double(c.points_rendered) * 1e-6);
          std::snprintf(bits, sizeof bits, "%u/%u/%u", c.batches_by_bits[0], c.batches_by_bits[1],
                        c.batches_by_bits[2]);
          std::snprintf(bpp, sizeof bpp, "%.1f", per_point);
          std::snprintf(gbs, sizeof gbs, "%.1f", rate);
          if (read_gbs > 0) std::snprintf(pct, sizeof pct, "%.0f", 100.0 * rate / read_gbs);
          run["batches_processed"] = c.batches_processed;
          run["batches_rendered"] = c.batches_rendered;
          run["batches_culled"] = c.batches_culled;
          run["points_rendered"] = c.points_rendered;
          run["batches_by_bits"] = {c.batches_by_bits[0], c.batches_by_bits[1],
                                    c.batches_by_bits[2]};
          run["points_by_bits"] = {c.points_by_bits[0], c.points_by_bits[1], c.points_by_bits[2]};
          run["bytes_per_point_loaded"] = per_point;
          run["loaded_gb_per_s"] = rate;
          run["visibility64"] = pipeline->visibility64;
          if (pipeline->kernel.fallback_events == pc::AutoSwitch::On && !pipeline->visibility64) {
            run["events"] = c.events;
            run["events_overflowed"] = c.events_overflowed;
            std::printf("  (%s %s: %.1fM winner events, %.2f a pixel%s)\n", v.name.c_str(),
                        variant.name.c_str(), double(c.events) * 1e-6,
                        double(c.events) / (double(args.width) * args.height),
                        c.events_overflowed ? ", overflowed: the colour pass ran" : "");
          }
          run["percent_of_read_bound"] = read_gbs > 0 ? 100.0 * rate / read_gbs : 0.0;
        } else {
          double rate = ms > 0 ? 16.0 * double(n) / (ms * 1e-3) * 1e-9 : 0.0;
          std::snprintf(bpp, sizeof bpp, "16.0");
          std::snprintf(gbs, sizeof gbs, "%.1f", rate);
          if (read_gbs > 0) std::snprintf(pct, sizeof pct, "%.0f", 100.0 * rate / read_gbs);
          run["bytes_per_point_loaded"] = 16.0;
          run["loaded_gb_per_s"] = rate;
        }
        out["runs"].push_back(run);
        // The accumulation pass (HQS sums, the fallback's colours), where the variant has one.
        char accumulation[16] = "-";
        if (pass_ms.count("raster-accumulate"))
          std::snprintf(accumulation, sizeof accumulation, "%.3f",
                        median(pass_ms["raster-accumulate"]));
        std::printf("%-6.0f %-9s %-17s %9.3f %9.3f %9s %8.2f %15s %13s %19s %6s %7s %5s\n",
                    double(n) * 1e-6, v.name.c_str(), variant.name.c_str(), ms, geom, accumulation,
                    ms > 0 ? double(n) / (ms * 1e-3) * 1e-9 : 0.0, batches, rendered, bits, bpp,
                    gbs, pct);
        std::fflush(stdout);
      }
    }
  }
  std::printf(
      "\nframe ms: all passes of a frame (clear, geometry, resolve/accumulate, display), "
      "median of %u; geom ms, acc ms: the depth and accumulation passes; Gpts/s: all N points "
      "per frame time; GB/s: point data loaded per second; %%bound: of the read kernel's "
      "bandwidth\n",
      args.frames);
  if (!args.json.empty()) {
    write_file_atomically(args.json, out.dump(2) + "\n");
  }
}

}  // namespace

void add_bench_raster_command(CLI::App& bench) {
  auto args = std::make_shared<RasterArgs>();
  auto* cmd = bench.add_subcommand(
      "raster", "Compute rasterizer vs billboards on the built-in scene (seed 001, Tables 1-2)");
  cmd->add_option("--points", args->points, "Scene sizes in points (several allowed)")
      ->capture_default_str();
  cmd->add_option("--width", args->width, "Image width")->capture_default_str();
  cmd->add_option("--height", args->height, "Image height")->capture_default_str();
  cmd->add_option("--frames", args->frames, "Timed frames per variant")
      ->check(CLI::Range(1u, 10000u))
      ->capture_default_str();
  cmd->add_option("--warmup", args->warmup, "Untimed frames first")->capture_default_str();
  cmd->add_option("--backend", args->backend, "WebGPU implementation: dawn or wgpu")
      ->check(CLI::IsMember({"dawn", "wgpu", "wgpu-native"}));
  cmd->add_option("--order", args->order, "Point order inside batches: morton, hilbert, none")
      ->check(CLI::IsMember({"morton", "hilbert", "none"}))
      ->capture_default_str();
  cmd->add_option("--copy-mb", args->copy_mb,
                  "Size of the bandwidth measurements (read kernel, copy) in MiB")
      ->capture_default_str();
  cmd->add_option("--variants", args->variants,
                  "Only these variants (default: all but the measurements): compute-basic, "
                  "compute-precision, compute-hqs, compute-fallback32, dilate-3px, "
                  "billboard-1px; measurements with wrong images, to combine with one: "
                  "no-atomic, no-write, no-early, no-load, no-sums, no-count; a+b combines "
                  "them, e.g. compute-hqs+no-sums")
      ->delimiter(',');
  cmd->add_flag("!--no-billboard", args->billboard, "Skip the billboard variant (saves 16 B/pt)");
  cmd->add_option("--seed", args->seed, "Scene seed")->capture_default_str();
  cmd->add_option("--json", args->json, "Write the results as JSON");
  cmd->callback([args] { run_raster_bench(*args); });
}

}  // namespace stipple::app
