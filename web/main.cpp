// The web viewer's program: libstipple's engine, plugins, render graph and shaders on the
// browser's WebGPU (a thin front end, as app/ is for the command line). It renders what
// `stipple render` renders for the same options (the built-in scene so far), draws the image
// on the page's canvas and reports on the page (window.stipple: done, error, stats).
#include <emscripten.h>

#include <cstdio>
#include <cstdlib>
#include <exception>
#include <memory>
#include <string>
#include <vector>

#include <fmt/format.h>

#include "stipple/core/error.hpp"
#include "stipple/engine/engine.hpp"
#include "stipple/engine/plugins.hpp"
#include "stipple/engine/render_plugins.hpp"
#include "stipple/math/camera.hpp"
#include "stipple/pointcloud/compute_raster.hpp"
#include "stipple/pointcloud/point_cloud.hpp"
#include "stipple/pointcloud/point_cloud_plugin.hpp"
#include "stipple/pointcloud/point_renderer.hpp"
#include "stipple/pointcloud/scene.hpp"

namespace {

using namespace stipple;

struct Options {
  uint32_t width = 1280, height = 720;
  uint64_t scene_points = 1'000'000;
  uint32_t seed = 1;
  double azimuth = 30.0, elevation = 40.0, fov = 50.0;
};

uint64_t number(const std::string& name, const char* value) {
  char* end = nullptr;
  unsigned long long v = std::strtoull(value, &end, 10);
  if (!*value || *end) fail("{}: not a number: '{}'", name, value);
  return v;
}

Options parse(int argc, char** argv) {
  Options o;
  for (int i = 1; i < argc; ++i) {
    std::string a = argv[i];
    if (i + 1 >= argc) fail("{}: a value is missing", a);
    const char* v = argv[++i];
    if (a == "--width")
      o.width = uint32_t(number(a, v));
    else if (a == "--height")
      o.height = uint32_t(number(a, v));
    else if (a == "--scene-points")
      o.scene_points = number(a, v);
    else if (a == "--seed")
      o.seed = uint32_t(number(a, v));
    else
      fail("unknown option '{}'", a);
  }
  if (o.width == 0 || o.height == 0 || o.width > 8192 || o.height > 8192)
    fail("the image size must be 1..8192 pixels a side");
  return o;
}

// Draws RGBA8 pixels on the page's canvas (#canvas, resized to the image).
void show(const gpu::Image& image) {
  EM_ASM(
      {
        const canvas = document.getElementById('canvas');
        canvas.width = $0;
        canvas.height = $1;
        const pixels = new Uint8ClampedArray(HEAPU8.subarray($2, $2 + $0 * $1 * 4));
        canvas.getContext('2d').putImageData(new ImageData(pixels, $0, $1), 0, 0);
      },
      image.width, image.height, image.rgba.data());
}

void report(const char* key, const std::string& value) {
  EM_ASM({ Module.stippleReport(UTF8ToString($0), UTF8ToString($1)); }, key, value.c_str());
}

void run(const Options& o) {
  Engine engine;
  engine.add_plugins(TimePlugin{}, TransformPlugin{}, CameraPlugin{});
  GpuPlugin gpu;
  gpu.options.optional_features = pc::compute_raster_features();
  engine.add_plugin(std::move(gpu));
  RenderGraphPlugin graph;
  graph.keep_history = true;
  engine.add_plugin(std::move(graph));
  pc::PointCloudPlugin points;
  points.inputs.scene.point_count = o.scene_points;
  points.inputs.scene.seed = o.seed;
  engine.add_plugin(std::move(points));
  engine.add_plugin(HeadlessTargetPlugin{o.width, o.height, "", 1});
  auto captured = std::make_shared<gpu::Image>();
  engine.render().insert_resource(
      FrameCapture{[captured](uint64_t, const gpu::Image& image) { *captured = image; }});

  // The camera and point size as `stipple render` chooses them (fitted to the points).
  Registry& main = engine.main();
  ViewFit fit(o.width, o.height, o.azimuth, o.elevation, o.fov);
  main.view<pc::PointCloudData>().each([&](const pc::PointCloudData& data) {
    if (data.cloud) pc::fit_cloud(fit, *data.cloud);
  });
  if (fit.empty()) fit.add_corners(main.resource<pc::SceneInfo>().world_bounds);
  const Camera camera = fit.camera();
  main.emplace<Camera>(main.create(), camera);
  auto& settings = main.resource<pc::PointDrawSettings>();
  main.view<pc::PointCloudData>().each([&](const pc::PointCloudData& data) {
    if (settings.render.point_size <= 0)
      settings.render.point_size = pc::auto_point_size(*data.cloud, camera, o.height);
  });
  // As `stipple render --renderer auto`: 1-pixel points go to the compute rasterizer.
  const char* renderer = "billboard";
  if (o.scene_points >= 10'000'000 || settings.render.point_size <= 1.0f) {
    settings.compute = true;
    settings.hqs = settings.render.splat == pc::SplatMode::Blend;
    renderer = "compute";
  }
  const double start = emscripten_get_now();
  engine.run();
  engine.shutdown();
  const double ms = emscripten_get_now() - start;
  if (captured->rgba.empty()) fail("no frame was drawn");
  show(*captured);
  const auto& description = main.resource<GpuContext>()->description;
  report("renderer", renderer);
  report("adapter", fmt::format("{} {} ({})", description.vendor, description.architecture,
                                description.backend));
  report("points", std::to_string(main.resource<pc::SceneInfo>().points));
  report("pointSize", fmt::format("{:.3f}", settings.render.point_size));
  report("ms", fmt::format("{:.1f}", ms));
}

}  // namespace

int main(int argc, char** argv) {
  try {
    run(parse(argc, argv));
    report("done", "1");
    return 0;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "stipple: %s\n", e.what());
    report("error", e.what());
    return 1;
  }
}
