// An engine of one's own over the installed libstipple: the library's plugins composed by hand
// (no command line), a LAS file read by pc::PointCloudPlugin, and a plugin of this program,
// FramePlugin, that adds a render-graph pass drawing a coloured frame around the image after the
// points. It renders headless to a PNG, reads the PNG back and checks it: the frame has the
// frame's colour, and points cover the inside. Exit 0 only then.
//
//   custom_pass INPUT.las OUTPUT.png
#include <array>
#include <cstdio>
#include <exception>
#include <string_view>

#include "stipple/core/error.hpp"
#include "stipple/engine/camera.hpp"
#include "stipple/engine/engine.hpp"
#include "stipple/engine/plugins.hpp"
#include "stipple/engine/render_plugins.hpp"
#include "stipple/math/camera.hpp"
#include "stipple/pointcloud/point_cloud_plugin.hpp"
#include "stipple/renderer/png.hpp"

using namespace stipple;

namespace {

constexpr uint32_t kWidth = 640, kHeight = 400, kFramePx = 6;
constexpr std::array<uint8_t, 3> kFrameColor{255, 128, 0};

// A full-screen triangle whose fragments inside the frame are discarded.
constexpr std::string_view kFrameShader = R"(
struct Frame { size: vec2<f32>, width: f32, pad: f32, color: vec4<f32> };
@group(0) @binding(0) var<uniform> frame: Frame;
@vertex fn vs_fullscreen(@builtin(vertex_index) i: u32) -> @builtin(position) vec4<f32> {
  let uv = vec2<f32>(f32((i << 1u) & 2u), f32(i & 2u));
  return vec4<f32>(uv * 2.0 - 1.0, 0.0, 1.0);
}
@fragment fn fs_main(@builtin(position) p: vec4<f32>) -> @location(0) vec4<f32> {
  let d = min(min(p.x, p.y), min(frame.size.x - p.x, frame.size.y - p.y));
  if (d > frame.width) { discard; }
  return frame.color;
}
)";

struct FrameUniforms {
  float size[2];
  float width, pad;
  float color[4];
};

// Render-world resource: the pass's GPU objects, made for the target's format on first use.
struct FrameResources {
  WGPUTextureFormat format = WGPUTextureFormat_Undefined;
  gpu::RenderPipeline pipeline;
  gpu::Buffer uniforms;
  gpu::BindGroup group;
};

// RenderStage::PreDraw (after the scene's passes were queued): one more pass writing "color".
void queue_frame(Registry& render) {
  auto& fg = render.resource<FrameGraph>();
  if (!fg.active) return;
  const auto& target = render.resource<RenderTarget>();
  auto& r = render.resource<FrameResources>();
  gpu::Context& ctx = *render.resource<GpuContext>();
  if (r.format != target.format) {
    gpu::ShaderModule module = gpu::create_shader(ctx, kFrameShader, "frame");
    r.pipeline = gpu::create_fullscreen_pipeline(
        ctx, {.module = module.get(), .format = target.format, .label = "frame"});
    r.uniforms = gpu::create_buffer(ctx, sizeof(FrameUniforms),
                                    WGPUBufferUsage_Uniform | WGPUBufferUsage_CopyDst, "frame");
    gpu::BindGroupLayout layout = gpu::bind_group_layout_of(r.pipeline);
    r.group = gpu::create_bind_group(ctx, layout.get(), {gpu::bind_buffer(0, r.uniforms.get())});
    r.format = target.format;
  }
  FrameUniforms u{{float(target.width), float(target.height)},
                  float(kFramePx),
                  0.0f,
                  {kFrameColor[0] / 255.0f, kFrameColor[1] / 255.0f, kFrameColor[2] / 255.0f, 1}};
  gpu::write_buffer(ctx, r.uniforms.get(), 0, u);
  fg.graph
      .add_pass("frame", gpu::PassKind::Render,
                [&r](gpu::PassContext& pc) {
                  gpu::draw_fullscreen(pc, pc.view("color"), r.pipeline.get(), {r.group.get()});
                })
      .write("color");
}

// A plugin is any type with build(Engine&); name and dependencies let the engine order and check
// plugins.
struct FramePlugin {
  static constexpr std::string_view name = "FramePlugin";
  static constexpr std::string_view description = "draws a frame around the image (example)";
  static constexpr std::array<std::string_view, 2> dependencies{"GpuPlugin", "RenderGraphPlugin"};
  void build(Engine& engine) {
    engine.render().insert_resource(FrameResources{});
    engine.add_system(RenderStage::PreDraw, queue_frame, "queue_frame");
  }
};

int check(const char* path) {
  gpu::Image image = gpu::read_png(path);
  if (image.width != kWidth || image.height != kHeight) {
    std::fprintf(stderr, "%s: %ux%u, expected %ux%u\n", path, image.width, image.height, kWidth,
                 kHeight);
    return 1;
  }
  auto pixel = [&](uint32_t x, uint32_t y) { return &image.rgba[(size_t(y) * kWidth + x) * 4]; };
  // Every pixel of the frame has its colour.
  uint64_t frame_pixels = 0, wrong = 0;
  for (uint32_t y = 0; y < kHeight; ++y)
    for (uint32_t x = 0; x < kWidth; ++x) {
      uint32_t d = std::min(std::min(x, y), std::min(kWidth - 1 - x, kHeight - 1 - y));
      if (d + 1 > kFramePx) continue;  // pixel centres within kFramePx of the edge
      ++frame_pixels;
      const uint8_t* p = pixel(x, y);
      if (p[0] != kFrameColor[0] || p[1] != kFrameColor[1] || p[2] != kFrameColor[2]) ++wrong;
    }
  // Inside, the points: most pixels differ from the background (the default dark blue-grey).
  uint64_t inside = 0, covered = 0;
  for (uint32_t y = kHeight / 4; y < kHeight * 3 / 4; ++y)
    for (uint32_t x = kWidth / 4; x < kWidth * 3 / 4; ++x) {
      const uint8_t* p = pixel(x, y);
      ++inside;
      if (std::abs(int(p[0]) - 18) + std::abs(int(p[1]) - 20) + std::abs(int(p[2]) - 26) > 12)
        ++covered;
    }
  std::printf("%s: frame %llu of %llu pixels right; points cover %.0f%% of the centre\n", path,
              static_cast<unsigned long long>(frame_pixels - wrong),
              static_cast<unsigned long long>(frame_pixels), 100.0 * covered / inside);
  return wrong == 0 && frame_pixels > 0 && covered * 2 > inside ? 0 : 1;
}

}  // namespace

int main(int argc, char** argv) {
  if (argc != 3) {
    std::fprintf(stderr, "usage: %s INPUT.las OUTPUT.png\n", argv[0]);
    return 2;
  }
  try {
    Engine engine;
    engine.add_plugins(TimePlugin{}, TransformPlugin{}, CameraPlugin{}, GpuPlugin{},
                       RenderGraphPlugin{});
    pc::PointCloudPlugin points;
    points.inputs.files = {argv[1]};
    engine.add_plugin(std::move(points));
    engine.add_plugin(FramePlugin{});
    engine.add_plugin(HeadlessTargetPlugin{kWidth, kHeight, argv[2], 1});
    // The camera frames what was loaded; the point size closes the gaps from there.
    Registry& main = engine.main();
    const auto& scene = main.resource<pc::SceneInfo>();
    Camera camera = frame_box(scene.world_bounds, double(kWidth) / kHeight);
    main.emplace<Camera>(main.create(), camera);
    auto& settings = main.resource<pc::PointDrawSettings>();
    settings.render.point_size =
        pc::auto_point_size(scene.world_bounds, scene.points, camera, kHeight);
    engine.run();
    engine.shutdown();
    return check(argv[2]);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "custom_pass: %s\n", e.what());
    return 1;
  }
}
