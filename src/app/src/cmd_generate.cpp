// `stipple generate`: writes the built-in procedural scene as LAS/LAZ, streaming, so inputs of
// hundreds of millions of points can be made on any machine; or, to a .ply or .spz, the same
// scene's points as Gaussian splats (inputs for the splat tiler and its benchmarks).
#include <proj.h>

#include <algorithm>
#include <chrono>
#include <cmath>
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
#include "stipple/io/splats.hpp"
#include "stipple/tiler/spz_writer.hpp"

namespace stipple::app {
namespace {

struct GenerateArgs {
  std::string output;
  uint64_t points = 1'000'000;
  uint32_t seed = 1;
  int point_format = 7;
  unsigned threads = 0;
  int sh_degree = 0;
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

// The scene's points as splats: flat ellipses of about the point spacing, randomly turned, the
// points' colours as SH DC, small random higher SH, opacity 0.5-1. Local metres about the scene's
// origin, in each format's own axes: an INRIA PLY is x right, y down, z forward (east, -up,
// north), SPZ y up, z back (east, up, -north), so both open the right way up.
// .ply is streamed (any count); .spz is encoded in memory (SPZ's arrays are attribute-major).
void run_generate_splats(const GenerateArgs& args, bool ply) {
  const auto start = std::chrono::steady_clock::now();
  io::SceneParams scene;
  scene.point_count = args.points;
  scene.seed = args.seed;
  const int degree = args.sh_degree;
  const size_t rc = size_t((degree + 1) * (degree + 1) - 1);
  std::FILE* out = nullptr;
  if (ply) {
    out = std::fopen(args.output.c_str(), "wb");
    if (!out) fail("{}: cannot create", args.output);
    std::string header = fmt::format(
        "ply\nformat binary_little_endian 1.0\ncomment stipple generate (procedural scene as "
        "splats)\nelement vertex {}\n",
        args.points);
    std::vector<std::string> props = {"x", "y", "z", "f_dc_0", "f_dc_1", "f_dc_2"};
    for (size_t k = 0; k < 3 * rc; ++k) props.push_back(fmt::format("f_rest_{}", k));
    for (const char* p :
         {"opacity", "scale_0", "scale_1", "scale_2", "rot_0", "rot_1", "rot_2", "rot_3"})
      props.push_back(p);
    for (const std::string& p : props) header += "property float " + p + "\n";
    header += "end_header\n";
    std::fwrite(header.data(), 1, header.size(), out);
  }
  io::SplatSet all;
  all.sh_degree = degree;
  const uint64_t block = 1 << 20;
  Progress progress("generating", args.points);
  std::vector<float> recs;
  for (uint64_t first = 0; first < args.points; first += block) {
    const uint64_t count = std::min(block, args.points - first);
    io::PointBatch batch;
    io::generate_scene(scene, first, count, batch);
    uint64_t state = (uint64_t(args.seed) << 32) ^ (first * 0x9E3779B97F4A7C15ull + 1);
    auto rand01 = [&] {
      state = state * 6364136223846793005ull + 1442695040888963407ull;
      return float(double(state >> 40) / double(1 << 24));
    };
    io::SplatSet s;
    s.sh_degree = degree;
    for (size_t i = 0; i < batch.size(); ++i) {
      const glm::dvec3 l = batch.positions[i] - scene.origin;  // east, north, up
      s.positions.push_back(ply ? glm::vec3(float(l.x), float(-l.z), float(l.y))
                                : glm::vec3(float(l.x), float(l.z), float(-l.y)));
      s.scales.push_back(
          glm::vec3(0.08f + 0.12f * rand01(), 0.08f + 0.12f * rand01(), 0.01f + 0.02f * rand01()));
      glm::vec4 q(rand01() - 0.5f, rand01() - 0.5f, rand01() - 0.5f, rand01() - 0.5f);
      const float len = std::sqrt(glm::dot(q, q));
      s.rotations.push_back(len > 1e-6f ? q / len : glm::vec4(0, 0, 0, 1));
      s.opacities.push_back(0.5f + 0.5f * rand01());
      glm::vec3 c(0.5f);
      if (!batch.rgb.empty())
        c = glm::min(glm::vec3(batch.rgb[i]) / 255.0f, glm::vec3(1.0f));  // 8-bit
      s.sh_dc.push_back((c - 0.5f) / 0.28209479177387814f);
      for (size_t k = 0; k < rc; ++k)
        s.sh_rest.push_back(0.1f * glm::vec3(rand01() - 0.5f, rand01() - 0.5f, rand01() - 0.5f));
    }
    if (ply) {
      const size_t stride = 14 + 3 * rc;
      recs.assign(s.size() * stride, 0.0f);
      for (size_t i = 0; i < s.size(); ++i) {
        float* r = recs.data() + i * stride;
        const glm::vec3 p = s.positions[i], dc = s.sh_dc[i];
        const glm::vec4 q = s.rotations[i];
        float head[6] = {p.x, p.y, p.z, dc.x, dc.y, dc.z};
        std::copy(head, head + 6, r);
        for (int c = 0; c < 3; ++c)  // f_rest is channel-major
          for (size_t k = 0; k < rc; ++k) r[6 + size_t(c) * rc + k] = s.sh_rest[i * rc + k][c];
        float* t = r + 6 + 3 * rc;
        const float a = s.opacities[i];
        t[0] = std::log(a / (1.0f - a + 1e-6f));
        for (int k = 0; k < 3; ++k) t[1 + k] = std::log(s.scales[i][k]);
        t[4] = q.w, t[5] = q.x, t[6] = q.y, t[7] = q.z;
      }
      if (std::fwrite(recs.data(), 4, recs.size(), out) != recs.size()) {
        std::fclose(out);
        fail("{}: write failed", args.output);
      }
    } else {
      io::append_splats(all, s);
    }
    progress.advance(count);
  }
  progress.finish();
  if (ply) {
    if (std::fclose(out) != 0) fail("{}: write failed", args.output);
  } else {
    const std::vector<uint8_t> bytes = tiler::encode_spz(all);
    std::FILE* f = std::fopen(args.output.c_str(), "wb");
    if (!f) fail("{}: cannot create", args.output);
    const bool ok = std::fwrite(bytes.data(), 1, bytes.size(), f) == bytes.size();
    if (std::fclose(f) != 0 || !ok) fail("{}: write failed", args.output);
  }
  const double seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  std::printf("wrote %llu splats (SH degree %d) to %s in %.2f s\n",
              static_cast<unsigned long long>(args.points), degree, args.output.c_str(), seconds);
}

}  // namespace

void add_generate_command(CLI::App& cli) {
  auto args = std::make_shared<GenerateArgs>();
  auto* cmd = cli.add_subcommand(
      "generate",
      "Write the built-in procedural scene (terrain, buildings, trees sampled like an "
      "airborne scan) as LAS or LAZ, of any size; or as Gaussian splats (.ply, .spz)");
  cmd->add_option("-o,--output", args->output,
                  "Output .las or .laz; .ply (INRIA layout) or .spz writes splats")
      ->required();
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
  cmd->add_option("--sh-degree", args->sh_degree, "Splats: SH degree (0-3)")
      ->check(CLI::Range(0, 3))
      ->capture_default_str();
  cmd->callback([args] {
    std::string ext = std::filesystem::path(args->output).extension().string();
    std::transform(ext.begin(), ext.end(), ext.begin(), ::tolower);
    if (ext == ".ply" || ext == ".spz")
      run_generate_splats(*args, ext == ".ply");
    else
      run_generate(*args);
  });
}

}  // namespace stipple::app
