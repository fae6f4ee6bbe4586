// `stipple generate`: writes the built-in procedural scene as LAS/LAZ, streaming, so inputs of
// hundreds of millions of points can be made on any machine.
#include <proj.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <deque>
#include <filesystem>
#include <future>
#include <string>

#include "stipple/app/commands.hpp"
#include "stipple/core/error.hpp"
#include "stipple/core/progress.hpp"
#include "stipple/core/thread_pool.hpp"
#include "stipple/io/las.hpp"
#include "stipple/io/procedural.hpp"

namespace stipple::app {
namespace {

struct GenerateArgs {
  std::string output;
  uint64_t points = 1'000'000;
  uint32_t seed = 1;
  int point_format = 7;
  unsigned threads = 0;
};

// The OGC WKT of an EPSG code, as LAS 1.4 wants it in its WKT VLR.
std::string epsg_wkt(int epsg) {
  PJ_CONTEXT* ctx = proj_context_create();
  PJ* crs = proj_create(ctx, fmt::format("EPSG:{}", epsg).c_str());
  std::string wkt;
  if (crs) {
    const char* text = proj_as_wkt(ctx, crs, PJ_WKT1_GDAL, nullptr);
    if (text) wkt = text;
    proj_destroy(crs);
  }
  proj_context_destroy(ctx);
  if (wkt.empty()) fail("PROJ has no definition of EPSG:{} (is proj-data installed?)", epsg);
  return wkt;
}

void run_generate(const GenerateArgs& args) {
  auto start = std::chrono::steady_clock::now();
  io::SceneParams scene;
  scene.point_count = args.points;
  scene.seed = args.seed;
  io::LasWriteOptions options;
  options.version_minor = 4;
  options.point_format = uint8_t(args.point_format);
  options.scale = glm::dvec3(0.001);
  options.offset = glm::floor(scene.origin / 1000.0) * 1000.0;
  std::string ext = std::filesystem::path(args.output).extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(), ::tolower);
  options.compress = ext == ".laz";
  options.wkt = epsg_wkt(scene.epsg);

  // Blocks are generated in parallel and written in order; a few blocks in flight bound memory.
  io::LasWriter writer(args.output, options);
  ThreadPool pool(args.threads ? args.threads : std::max(1u, std::thread::hardware_concurrency()));
  const uint64_t block = 1 << 20;
  const size_t in_flight = pool.size() * 2;
  std::deque<std::future<io::PointBatch>> pending;
  uint64_t next = 0;
  Progress progress("generating", args.points);
  auto launch = [&] {
    uint64_t first = next, count = std::min(block, args.points - next);
    next += count;
    auto promise = std::make_shared<std::promise<io::PointBatch>>();
    pending.push_back(promise->get_future());
    pool.submit([&scene, first, count, promise] {
      try {
        io::PointBatch batch;
        io::generate_scene(scene, first, count, batch);
        promise->set_value(std::move(batch));
      } catch (...) {
        promise->set_exception(std::current_exception());
      }
    });
  };
  while (next < args.points && pending.size() < in_flight) launch();
  while (!pending.empty()) {
    io::PointBatch batch = pending.front().get();
    pending.pop_front();
    if (next < args.points) launch();
    writer.write(batch);
    progress.advance(batch.size());
  }
  writer.close();
  progress.finish();
  double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  std::printf("wrote %llu points to %s (LAS 1.4 format %d%s, EPSG:%d) in %.2f s\n",
              static_cast<unsigned long long>(args.points), args.output.c_str(), args.point_format,
              options.compress ? ", LAZ" : "", scene.epsg, seconds);
}

}  // namespace

void add_generate_command(CLI::App& cli) {
  auto args = std::make_shared<GenerateArgs>();
  auto* cmd = cli.add_subcommand(
      "generate",
      "Write the built-in procedural scene (terrain, buildings, trees sampled like an "
      "airborne scan) as LAS or LAZ, of any size");
  cmd->add_option("-o,--output", args->output, "Output .las or .laz")->required();
  cmd->add_option("-n,--points", args->points, "Number of points")
      ->check(CLI::Range(uint64_t(1), uint64_t(1) << 40))
      ->capture_default_str();
  cmd->add_option("--seed", args->seed, "Random seed")->capture_default_str();
  cmd->add_option("--point-format", args->point_format,
                  "LAS point format (2, 3, 5, 7, 8 or 10 "
                  "carry the scene's colours)")
      ->check(CLI::Range(0, 10))
      ->capture_default_str();
  cmd->add_option("--threads", args->threads, "Worker threads (default: all cores)");
  cmd->callback([args] { run_generate(*args); });
}

}  // namespace stipple::app
