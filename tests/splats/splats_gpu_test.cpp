// The splat passes (stipple/splats/splats.hpp) against a CPU reference renderer written here from
// the 3D Gaussian splatting reference rasterizer's rules (EWA projection with the 1.3 x tan(fov/2)
// clamp and 0.3 px, 3-sigma square, SH up to degree 3, alpha = min(0.99, opacity * exp(power)),
// alpha < 1/255 skipped, front-to-back blending that stops when transmittance falls under 1e-4),
// on both WebGPU implementations; and splats with points in one frame: the points' depth hides
// the splats behind them and not those in front.
#include <gtest/gtest.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <numeric>
#include <optional>
#include <random>
#include <thread>

#include <glm/gtc/matrix_transform.hpp>
#include <glm/gtc/quaternion.hpp>
#include <glm/mat3x3.hpp>
#include <glm/matrix.hpp>

#include "stipple/pointcloud/batches.hpp"
#include "stipple/pointcloud/compute_raster.hpp"
#include "stipple/pointcloud/point_cloud.hpp"
#include "stipple/pointcloud/point_renderer.hpp"
#include "stipple/renderer/gpu.hpp"
#include "stipple/renderer/render_graph.hpp"
#include "stipple/splats/splats.hpp"

using namespace stipple;

namespace {

constexpr double kSH0 = 0.28209479177387814;
constexpr double kSH1 = 0.4886025119029199;
constexpr double kSH2[5] = {1.0925484305920792, -1.0925484305920792, 0.31539156525252005,
                            -1.0925484305920792, 0.5462742152960396};
constexpr double kSH3[7] = {-0.5900435899266435, 2.890611442640554,   -0.4570457994644658,
                            0.3731763325901154,  -0.4570457994644658, 1.445305721320277,
                            -0.5900435899266435};

// RGB of splat i seen along `dir` (unit, in the set's frame): the reference's computeColorFromSH.
glm::dvec3 sh_color(const io::SplatSet& set, size_t i, const glm::dvec3& dir) {
  auto coef = [&](int k) { return glm::dvec3(set.sh_rest[i * set.rest_count() + size_t(k - 1)]); };
  glm::dvec3 c = kSH0 * glm::dvec3(set.sh_dc[i]);
  const double x = dir.x, y = dir.y, z = dir.z;
  if (set.sh_degree > 0) {
    c += -kSH1 * y * coef(1) + kSH1 * z * coef(2) - kSH1 * x * coef(3);
    if (set.sh_degree > 1) {
      const double xx = x * x, yy = y * y, zz = z * z;
      c += kSH2[0] * x * y * coef(4) + kSH2[1] * y * z * coef(5) +
           kSH2[2] * (2 * zz - xx - yy) * coef(6) + kSH2[3] * x * z * coef(7) +
           kSH2[4] * (xx - yy) * coef(8);
      if (set.sh_degree > 2)
        c += kSH3[0] * y * (3 * xx - yy) * coef(9) + kSH3[1] * x * y * z * coef(10) +
             kSH3[2] * y * (4 * zz - xx - yy) * coef(11) +
             kSH3[3] * z * (2 * zz - 3 * xx - 3 * yy) * coef(12) +
             kSH3[4] * x * (4 * zz - xx - yy) * coef(13) + kSH3[5] * z * (xx - yy) * coef(14) +
             kSH3[6] * x * (xx - 3 * yy) * coef(15);
    }
  }
  return glm::max(c + 0.5, glm::dvec3(0.0));
}

struct RefSplat {
  double depth;
  glm::dvec2 centre;
  double conic[3];
  double radius;
  double opacity;
  glm::dvec3 color;
};

// The reference renderer: RGB in [0, 1] per pixel, top row first.
std::vector<glm::dvec3> render_reference(const io::SplatSet& set, const Camera& camera, uint32_t w,
                                         uint32_t h, const glm::dvec3& background) {
  const glm::dmat3 flip(1, 0, 0, 0, -1, 0, 0, 0, -1);
  const glm::dmat3 world_to_view = flip * glm::dmat3(camera.view_rotation());
  const glm::dmat3 linear(set.transform);
  const glm::dvec3 translation(set.transform[3]);
  const double tan_y = std::tan(camera.fov_y / 2), tan_x = tan_y * w / h;
  const double fx = w / (2 * tan_x), fy = h / (2 * tan_y);
  std::vector<RefSplat> visible;
  for (size_t i = 0; i < set.size(); ++i) {
    const glm::dvec3 world = linear * glm::dvec3(set.positions[i]) + translation;
    const glm::dvec3 t = world_to_view * (world - camera.position);
    if (t.z <= camera.near_plane || set.opacities[i] < 1.0 / 255.0) continue;
    const glm::dvec4 q = glm::normalize(glm::dvec4(set.rotations[i]));
    const glm::dmat3 r = glm::mat3_cast(glm::dquat(q.w, q.x, q.y, q.z));
    const glm::dvec3 s(set.scales[i]);
    const glm::dmat3 m(r[0] * s.x, r[1] * s.y, r[2] * s.z);
    const glm::dmat3 sigma = m * glm::transpose(m);
    const double tx = std::clamp(t.x / t.z, -1.3 * tan_x, 1.3 * tan_x) * t.z;
    const double ty = std::clamp(t.y / t.z, -1.3 * tan_y, 1.3 * tan_y) * t.z;
    const glm::dmat3 j(glm::dvec3(fx / t.z, 0, 0), glm::dvec3(0, fy / t.z, 0),
                       glm::dvec3(-fx * tx / (t.z * t.z), -fy * ty / (t.z * t.z), 0));
    const glm::dmat3 tm = j * world_to_view * linear;
    const glm::dmat3 cov = tm * sigma * glm::transpose(tm);
    const double a = cov[0][0] + 0.3, b = cov[0][1], c = cov[1][1] + 0.3;
    const double det = a * c - b * b;
    if (det <= 0) continue;
    const double mid = 0.5 * (a + c);
    const double lambda = mid + std::sqrt(std::max(0.1, mid * mid - det));
    RefSplat rs;
    rs.radius = std::ceil(3 * std::sqrt(lambda));
    rs.centre = {fx * t.x / t.z + w / 2.0, fy * t.y / t.z + h / 2.0};
    rs.depth = t.z;
    rs.conic[0] = c / det;
    rs.conic[1] = -b / det;
    rs.conic[2] = a / det;
    rs.opacity = set.opacities[i];
    const glm::dvec3 dir = glm::normalize(glm::inverse(linear) * (world - camera.position));
    rs.color = sh_color(set, i, dir);
    visible.push_back(rs);
  }
  std::stable_sort(visible.begin(), visible.end(),
                   [](const RefSplat& a, const RefSplat& b) { return a.depth < b.depth; });
  std::vector<glm::dvec3> image(size_t(w) * h);
  for (uint32_t py = 0; py < h; ++py)
    for (uint32_t px = 0; px < w; ++px) {
      const glm::dvec2 pixel(px + 0.5, py + 0.5);
      glm::dvec3 c(0.0);
      double transmittance = 1.0;
      for (const RefSplat& s : visible) {
        const glm::dvec2 d = s.centre - pixel;
        if (std::abs(d.x) > s.radius || std::abs(d.y) > s.radius) continue;
        const double power =
            -0.5 * (s.conic[0] * d.x * d.x + s.conic[2] * d.y * d.y) - s.conic[1] * d.x * d.y;
        if (power > 0) continue;
        const double alpha = std::min(0.99, s.opacity * std::exp(power));
        if (alpha < 1.0 / 255.0) continue;
        const double next = transmittance * (1 - alpha);
        if (next < 1e-4) break;
        c += s.color * alpha * transmittance;
        transmittance = next;
      }
      image[size_t(py) * w + px] = c + transmittance * background;
    }
  return image;
}

// A few hundred splats of SH degree 3 in a box around the origin.
io::SplatSet random_splats(size_t n, uint32_t seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> u(0.0f, 1.0f);
  io::SplatSet set;
  set.sh_degree = 3;
  for (size_t i = 0; i < n; ++i) {
    set.positions.push_back({u(rng) * 3 - 1.5f, u(rng) * 2 - 1.0f, u(rng) * 2 - 1.0f});
    set.scales.push_back({0.02f + 0.15f * u(rng), 0.02f + 0.15f * u(rng), 0.01f + 0.05f * u(rng)});
    set.rotations.push_back(
        glm::normalize(glm::vec4(u(rng) - 0.5f, u(rng) - 0.5f, u(rng) - 0.5f, u(rng) - 0.5f)));
    set.opacities.push_back(0.1f + 0.9f * u(rng));
    set.sh_dc.push_back({u(rng) * 3 - 1.5f, u(rng) * 3 - 1.5f, u(rng) * 3 - 1.5f});
    for (size_t k = 0; k < set.rest_count(); ++k)
      set.sh_rest.push_back({u(rng) * 0.4f - 0.2f, u(rng) * 0.4f - 0.2f, u(rng) * 0.4f - 0.2f});
  }
  return set;
}

class Splats : public ::testing::TestWithParam<std::string> {
 protected:
  void SetUp() override {
    gpu::ContextOptions options;
    options.backend = GetParam();
    ctx = gpu::create_context(options);
  }
  std::unique_ptr<gpu::Context> ctx;
};

struct Target {
  gpu::Texture color, depth;
  gpu::TextureView color_view, depth_view;
};

// A colour target cleared to `background` and a depth target cleared to `depth` (reverse Z).
Target make_target(gpu::Context& ctx, uint32_t w, uint32_t h, const glm::dvec3& background,
                   float depth_value) {
  Target t;
  t.color = gpu::create_texture_2d(ctx, w, h, WGPUTextureFormat_RGBA8Unorm,
                                   WGPUTextureUsage_RenderAttachment | WGPUTextureUsage_CopySrc,
                                   "test-color");
  t.color_view = gpu::create_view(t.color);
  t.depth = gpu::create_texture_2d(
      ctx, w, h, WGPUTextureFormat_Depth32Float,
      WGPUTextureUsage_RenderAttachment | WGPUTextureUsage_TextureBinding, "test-depth");
  t.depth_view = gpu::create_view(t.depth);
  WGPUCommandEncoderDescriptor edesc = WGPU_COMMAND_ENCODER_DESCRIPTOR_INIT;
  gpu::CommandEncoder encoder(wgpuDeviceCreateCommandEncoder(ctx.device.get(), &edesc));
  WGPURenderPassColorAttachment color = WGPU_RENDER_PASS_COLOR_ATTACHMENT_INIT;
  color.view = t.color_view.get();
  color.loadOp = WGPULoadOp_Clear;
  color.storeOp = WGPUStoreOp_Store;
  color.clearValue = {background.r, background.g, background.b, 1.0};
  WGPURenderPassDepthStencilAttachment d = WGPU_RENDER_PASS_DEPTH_STENCIL_ATTACHMENT_INIT;
  d.view = t.depth_view.get();
  d.depthLoadOp = WGPULoadOp_Clear;
  d.depthStoreOp = WGPUStoreOp_Store;
  d.depthClearValue = depth_value;
  WGPURenderPassDescriptor desc = WGPU_RENDER_PASS_DESCRIPTOR_INIT;
  desc.colorAttachmentCount = 1;
  desc.colorAttachments = &color;
  desc.depthStencilAttachment = &d;
  gpu::RenderPassEncoder pass(wgpuCommandEncoderBeginRenderPass(encoder.get(), &desc));
  wgpuRenderPassEncoderEnd(pass.get());
  WGPUCommandBufferDescriptor bdesc = WGPU_COMMAND_BUFFER_DESCRIPTOR_INIT;
  gpu::CommandBuffer commands(wgpuCommandEncoderFinish(encoder.get(), &bdesc));
  WGPUCommandBuffer raw = commands.get();
  wgpuQueueSubmit(ctx.queue.get(), 1, &raw);
  return t;
}

Camera test_camera() {
  Camera camera;
  camera.look_at({0.5, 1.0, 5.0}, {0.0, 0.0, 0.0});
  camera.fov_y = glm::radians(45.0);
  return camera;
}

struct Difference {
  double mean = 0;    // mean absolute difference, 8-bit levels, over channels
  double within = 0;  // fraction of pixels whose channels all lie within the tolerance
  int max = 0;
  double covered = 0;  // fraction of reference pixels that differ from the background
};

Difference compare(const gpu::Image& image, const std::vector<glm::dvec3>& reference,
                   const glm::dvec3& background, int tolerance) {
  Difference d;
  size_t within = 0, covered = 0;
  double sum = 0;
  for (size_t i = 0; i < reference.size(); ++i) {
    bool ok = true, differs = false;
    for (int c = 0; c < 3; ++c) {
      const int ref = int(std::lround(std::clamp(reference[i][c], 0.0, 1.0) * 255));
      const int bg = int(std::lround(background[c] * 255));
      const int diff = std::abs(int(image.rgba[i * 4 + size_t(c)]) - ref);
      sum += diff;
      d.max = std::max(d.max, diff);
      ok = ok && diff <= tolerance;
      differs = differs || std::abs(ref - bg) > 2;
    }
    within += ok;
    covered += differs;
  }
  d.mean = sum / double(reference.size() * 3);
  d.within = double(within) / double(reference.size());
  d.covered = double(covered) / double(reference.size());
  return d;
}

// What the tile rasterizer's pair buffers did in draw_and_compare.
struct PairStats {
  uint32_t capacity = 0;  // after the frame
  uint64_t overflowed_frames = 0;
};

// Draws `gpu_splats` alone over the background and compares it with the reference renderer's
// image of `set`.
Difference draw_uploaded_and_compare(gpu::Context& ctx, splats::GpuSplats& gpu_splats,
                                     const io::SplatSet& set, const Camera& camera,
                                     uint32_t* visible, splats::SplatRasterizer rasterizer,
                                     uint32_t w = 200, uint32_t h = 150, PairStats* pairs = nullptr,
                                     splats::SplatPipelines* kept = nullptr) {
  const glm::dvec3 background(0.1, 0.2, 0.3);
  std::optional<splats::SplatPipelines> made;
  if (!kept) made.emplace(splats::create_splat_pipelines(ctx, WGPUTextureFormat_RGBA8Unorm));
  splats::SplatPipelines& pipelines = kept ? *kept : *made;
  Target target = make_target(ctx, w, h, background, 0.0f);
  splats::draw_splats(ctx, pipelines, gpu_splats, camera, target.color.get(),
                      target.color_view.get(), w, h, nullptr, nullptr, false, rasterizer);
  gpu::Image image = gpu::read_texture(ctx, target.color.get(), w, h, WGPUTextureFormat_RGBA8Unorm);
  *visible = splats::read_visible_count(ctx, gpu_splats);
  if (pairs) {
    pairs->capacity = splats::tile_pair_capacity(gpu_splats);
    pairs->overflowed_frames = gpu_splats.pair_counts.overflowed_frames;
  }
  Difference d = compare(image, render_reference(set, camera, w, h, background), background, 4);
  std::printf("visible %u of %zu, covered %.3f, mean |diff| %.3f levels, within 4: %.4f, max %d\n",
              *visible, set.size(), d.covered, d.mean, d.within, d.max);
  return d;
}

// Uploads `set`, draws it alone over the background and compares it with the reference.
Difference draw_and_compare(gpu::Context& ctx, const io::SplatSet& set, const Camera& camera,
                            uint32_t* visible,
                            splats::SplatRasterizer rasterizer = splats::SplatRasterizer::Quads,
                            uint32_t w = 200, uint32_t h = 150, PairStats* pairs = nullptr) {
  auto gpu_splats = splats::upload_splats(ctx, set);
  return draw_uploaded_and_compare(ctx, gpu_splats, set, camera, visible, rasterizer, w, h, pairs);
}

// Tolerance: the GPU blends into 8 bits after every splat and keeps SH, rotations and DC
// colours in f16; the reference is double precision, rounded once. Measured on lavapipe (both
// implementations): mean 0.44 levels, every pixel within 4.
void expect_close(const Difference& d) {
  EXPECT_GT(d.covered, 0.3);  // the image holds splats, not just background
  EXPECT_LT(d.mean, 1.0);
  EXPECT_GT(d.within, 0.99);
  EXPECT_LE(d.max, 12);
}

TEST_P(Splats, MatchTheCpuReference) {
  uint32_t visible = 0;
  Difference d = draw_and_compare(*ctx, random_splats(300, 11), test_camera(), &visible);
  EXPECT_EQ(visible, 300u);
  expect_close(d);
}

TEST_P(Splats, TileRasterizerMatchesTheCpuReference) {
  // The same splats through the 16x16-tile compute rasterizer (f32 blending, no per-splat
  // rounding to 8 bits): the same tolerance holds.
  uint32_t visible = 0;
  Difference d = draw_and_compare(*ctx, random_splats(300, 11), test_camera(), &visible,
                                  splats::SplatRasterizer::Tiles);
  EXPECT_EQ(visible, 300u);
  expect_close(d);
}

TEST_P(Splats, TileRasterizerMatchesTheCpuReferenceOverSeveralScanBlocks) {
  // 5000 small splats: the binning's prefix sum spans three blocks of 2048 ranks, so each
  // block's pairs land at its offset (misplaced pairs put splats in other tiles).
  io::SplatSet set = random_splats(5000, 41);
  for (glm::vec3& s : set.scales) s *= 0.3f;
  uint32_t visible = 0;
  Difference d =
      draw_and_compare(*ctx, set, test_camera(), &visible, splats::SplatRasterizer::Tiles);
  EXPECT_EQ(visible, 5000u);
  expect_close(d);
}

// A close-up: a few hundred large, faint splats around the camera's target, each covering much
// of a 320x240 view (300 tiles): about 250 tiles a splat, 60 times the first guess of 4, and
// over its floor of 65536 pairs.
io::SplatSet close_up_splats(size_t n, uint32_t seed) {
  io::SplatSet set = random_splats(n, seed);
  std::mt19937 rng(seed + 100);
  std::uniform_real_distribution<float> u(0.0f, 1.0f);
  for (size_t i = 0; i < n; ++i) {
    set.positions[i] *= 0.5f;
    set.scales[i] = {0.4f + 0.4f * u(rng), 0.4f + 0.4f * u(rng), 0.1f + 0.2f * u(rng)};
    set.opacities[i] = 0.02f + 0.08f * u(rng);  // faint: every layer shows through
  }
  return set;
}

TEST_P(Splats, TileRasterizerDrawsEverySplatOfACloseUp) {
  // The (tile, splat) pairs of the frame far exceed the buffers' first capacity: the frame is
  // drawn again once they have grown (draw_splats waits for its pair count), and matches the
  // reference. Dropped pairs would leave splats out of their tiles.
  const io::SplatSet set = close_up_splats(600, 21);
  Camera camera;
  camera.look_at({0.2, 0.3, 2.5}, {0.0, 0.0, 0.0});
  camera.fov_y = glm::radians(50.0);
  uint32_t visible = 0;
  PairStats pairs;
  Difference d = draw_and_compare(*ctx, set, camera, &visible, splats::SplatRasterizer::Tiles, 320,
                                  240, &pairs);
  std::printf("pair capacity %u, frames over it %llu\n", pairs.capacity,
              static_cast<unsigned long long>(pairs.overflowed_frames));
  EXPECT_EQ(visible, 600u);
  EXPECT_GT(d.covered, 0.9);  // the splats fill the view
  expect_close(d);
  EXPECT_EQ(pairs.overflowed_frames, 1u);  // the first frame, drawn again
  EXPECT_GT(pairs.capacity, 600u * 120);   // grew past 4 a splat (and the 65536 floor)
}

TEST_P(Splats, TilePairsGrowWithoutWaiting) {
  // The interactive path: frames through the graph, never waited for; the pair counts come back
  // later (settle_tile_pairs without waiting, as the plugin calls it before each frame) and the
  // buffers grow before the next frame, which is then whole.
  const io::SplatSet set = close_up_splats(600, 21);
  Camera camera;
  camera.look_at({0.2, 0.3, 2.5}, {0.0, 0.0, 0.0});
  camera.fov_y = glm::radians(50.0);
  const uint32_t w = 320, h = 240;
  auto pipelines = splats::create_splat_pipelines(*ctx, WGPUTextureFormat_RGBA8Unorm);
  auto gpu_splats = splats::upload_splats(*ctx, set);
  Target target = make_target(*ctx, w, h, glm::dvec3(0.0), 0.0f);
  gpu::TransientPool pool;
  auto frame = [&] {
    gpu::RenderGraph graph;
    graph.import_texture("color", target.color.get(), target.color_view.get(),
                         {w, h, WGPUTextureFormat_RGBA8Unorm, WGPUTextureUsage_RenderAttachment},
                         gpu::Access::Writable);
    splats::SplatPassTargets targets;
    targets.depth.clear();
    targets.rasterizer = splats::SplatRasterizer::Tiles;
    splats::add_splat_passes(graph, pipelines, gpu_splats, camera, w, h, targets);
    graph.execute(*ctx, pool);
    ctx->check("tile frame");
  };
  frame();
  const uint32_t first = splats::tile_pair_capacity(gpu_splats);
  EXPECT_EQ(first, 65536u);  // 4 a splat, at least 65536
  // Until the first frame's count has come back (no call waits; the bound is generous).
  bool grew = false;
  for (int i = 0; i < 60000 && !grew; ++i) {
    grew = splats::settle_tile_pairs(*ctx, gpu_splats, false);
    if (!grew) std::this_thread::sleep_for(std::chrono::milliseconds(1));
  }
  EXPECT_TRUE(grew);
  frame();
  EXPECT_GT(splats::tile_pair_capacity(gpu_splats), first);
  // The second frame fit: nothing more to grow.
  EXPECT_FALSE(splats::settle_tile_pairs(*ctx, gpu_splats, true));
  EXPECT_EQ(gpu_splats.pair_counts.overflowed_frames, 1u);
}

TEST_P(Splats, TilePairsPastTheLimitKeepTheNearestSplats) {
  // The close-up's splats and, nearest the camera, a small opaque green one; the pair buffers
  // may hold 70000 pairs (a lowered limit, above the first capacity of 65536), the frame wants
  // about 105000: the capacity stops at the limit, the frame is not redrawn for ever, and the
  // pairs left out are the farthest splats', so the green one shows.
  io::SplatSet set = close_up_splats(600, 21);
  set.positions.push_back({0.0f, 0.0f, 1.2f});
  set.scales.push_back({0.03f, 0.03f, 0.03f});
  set.rotations.push_back({0, 0, 0, 1});
  set.opacities.push_back(1.0f);
  set.sh_dc.push_back((glm::vec3(0, 1, 0) - 0.5f) / float(kSH0));
  set.sh_rest.resize(set.sh_rest.size() + set.rest_count(), glm::vec3(0.0f));
  Camera camera;
  camera.look_at({0.0, 0.0, 2.5}, {0.0, 0.0, 0.0});
  camera.fov_y = glm::radians(50.0);
  const uint32_t w = 320, h = 240;
  auto pipelines = splats::create_splat_pipelines(*ctx, WGPUTextureFormat_RGBA8Unorm);
  auto gpu_splats = splats::upload_splats(*ctx, set);
  gpu_splats.pair_counts.max_capacity = 70000;
  Target target = make_target(*ctx, w, h, glm::dvec3(0.0), 0.0f);
  splats::draw_splats(*ctx, pipelines, gpu_splats, camera, target.color.get(),
                      target.color_view.get(), w, h, nullptr, nullptr, false,
                      splats::SplatRasterizer::Tiles);
  EXPECT_EQ(splats::tile_pair_capacity(gpu_splats), 70000u);
  EXPECT_GT(gpu_splats.pair_counts.needed, 70000u);
  EXPECT_TRUE(gpu_splats.pair_counts.warned);
  // Drawn again once, grown to the limit; that frame overflowed too, with nothing more to grow.
  EXPECT_FALSE(splats::settle_tile_pairs(*ctx, gpu_splats, true));
  EXPECT_EQ(gpu_splats.pair_counts.overflowed_frames, 2u);
  gpu::Image image =
      gpu::read_texture(*ctx, target.color.get(), w, h, WGPUTextureFormat_RGBA8Unorm);
  const uint8_t* centre = &image.rgba[(size_t(h / 2) * w + w / 2) * 4];
  EXPECT_GT(centre[1], 200) << "the nearest splat is drawn";
  EXPECT_LT(centre[0], 60);
  EXPECT_LT(centre[2], 60);
}

TEST_P(Splats, TransformedSetMatchesTheReference) {
  // A set with a rotation, a non-uniform scale and a translation far from the origin, seen by a
  // camera there: the SH are evaluated in the set's own frame, the covariance goes through
  // the transform, and positions stay precise (camera-relative in double).
  io::SplatSet set = random_splats(250, 12);
  const glm::dvec3 far(1.0e5, 20.0, -3.0e5);
  set.transform = glm::translate(glm::dmat4(1.0), far) *
                  glm::rotate(glm::dmat4(1.0), 0.7, glm::dvec3(0.3, 1.0, 0.2)) *
                  glm::scale(glm::dmat4(1.0), glm::dvec3(1.2, 0.8, 1.0));
  Camera camera = test_camera();
  camera.position += far;
  uint32_t visible = 0;
  Difference d = draw_and_compare(*ctx, set, camera, &visible);
  EXPECT_GT(visible, 200u);
  expect_close(d);
}

// A streamed tileset's drawn tiles: sets in one frame, composed on the GPU into one set placed by
// a transform (compose_splats). Each part is packed and uploaded once; a later list reuses the
// uploaded parts and the set's buffers while they have room, and grows them when not; a part of
// a lower SH degree is padded with zeros. Every composition draws as the reference draws the
// parts' splats together.
TEST_P(Splats, ComposedPartsMatchTheReference) {
  const glm::dvec3 far(2.0e4, 10.0, -5.0e4);
  const glm::dmat4 transform = glm::translate(glm::dmat4(1.0), far) *
                               glm::rotate(glm::dmat4(1.0), 0.4, glm::dvec3(0.0, 1.0, 0.0));
  auto slice = [](const io::SplatSet& from, size_t first, size_t n, int degree) {
    io::SplatSet part;
    part.sh_degree = degree;
    for (size_t i = first; i < first + n; ++i) {
      part.positions.push_back(from.positions[i]);
      part.scales.push_back(from.scales[i]);
      part.rotations.push_back(from.rotations[i]);
      part.opacities.push_back(from.opacities[i]);
      part.sh_dc.push_back(from.sh_dc[i]);
      for (size_t k = 0; k < part.rest_count(); ++k)
        part.sh_rest.push_back(from.sh_rest[i * from.rest_count() + k]);
    }
    return std::make_shared<const io::SplatSet>(std::move(part));
  };
  const io::SplatSet source = random_splats(500, 21);
  const auto a = slice(source, 0, 100, 3), b = slice(source, 100, 100, 1),
             c = slice(source, 200, 100, 3);
  auto d = slice(source, 300, 200, 3);
  // The reference's set: the parts' splats in order at degree 3 (b's higher coefficients zero).
  auto together = [&](const std::vector<std::shared_ptr<const io::SplatSet>>& parts) {
    io::SplatSet all;
    all.sh_degree = 3;
    all.transform = transform;
    for (const auto& part : parts)
      for (size_t i = 0; i < part->size(); ++i) {
        all.positions.push_back(part->positions[i]);
        all.scales.push_back(part->scales[i]);
        all.rotations.push_back(part->rotations[i]);
        all.opacities.push_back(part->opacities[i]);
        all.sh_dc.push_back(part->sh_dc[i]);
        for (size_t k = 0; k < all.rest_count(); ++k)
          all.sh_rest.push_back(k < part->rest_count() ? part->sh_rest[i * part->rest_count() + k]
                                                       : glm::vec3(0.0f));
      }
    return all;
  };
  Camera camera = test_camera();
  camera.position = glm::dvec3(transform * glm::dvec4(camera.position, 1.0));
  camera.look_at(camera.position, far);
  // One set of pipelines, as the plugin keeps: the set's bind groups, sort and tile buffers are
  // reused across compositions while it has room.
  auto pipelines = splats::create_splat_pipelines(*ctx, WGPUTextureFormat_RGBA8Unorm);
  splats::SplatPartCache cache;
  std::unique_ptr<splats::GpuSplats> composed;
  auto check = [&](const std::vector<std::shared_ptr<const io::SplatSet>>& parts, uint64_t packed,
                   uint32_t capacity, double least_covered = 0.3) {
    splats::compose_splats(*ctx, cache, composed, parts, transform);
    EXPECT_EQ(cache.packed_splats, packed);
    EXPECT_EQ(composed->capacity, capacity);
    const io::SplatSet all = together(parts);
    for (auto rasterizer : {splats::SplatRasterizer::Quads, splats::SplatRasterizer::Tiles}) {
      SCOPED_TRACE(splats::splat_rasterizer_name(rasterizer));
      uint32_t visible = 0;
      const Difference d = draw_uploaded_and_compare(*ctx, *composed, all, camera, &visible,
                                                     rasterizer, 200, 150, nullptr, &pipelines);
      EXPECT_GT(d.covered, least_covered);
      EXPECT_LT(d.mean, 1.0);
      EXPECT_GT(d.within, 0.99);
      EXPECT_LE(d.max, 12);
      EXPECT_EQ(visible, all.size());
    }
  };
  check({a, b, c}, 300, 450);  // every part packed; room for half again
  const splats::GpuSplats* kept = composed.get();
  check({c, a}, 300, 450);  // nothing packed, the same buffers, another order
  EXPECT_EQ(composed.get(), kept);
  check({a, b, c, d}, 500, 750);  // only d packed; 500 splats outgrow 450: new buffers
  EXPECT_EQ(cache.parts.size(), 4u);
  kept = composed.get();
  d.reset();                  // evicted: its upload goes at the next composition
  check({b}, 500, 750, 0.2);  // degree 1 alone (100 splats cover 26 %): the set stays at
                              // degree 3, b is not packed again
  EXPECT_EQ(composed.get(), kept);
  EXPECT_EQ(cache.parts.size(), 3u);
  splats::compose_splats(*ctx, cache, composed, {}, transform);  // nothing drawn
  EXPECT_EQ(composed.get(), kept);
  EXPECT_EQ(composed->count, 0u);
  composed.reset();
}

TEST_P(Splats, CulledBehindTheCameraAndOffScreen) {
  io::SplatSet set = random_splats(3, 13);
  set.positions = {{0, 0, 0}, {0, 0, 10}, {40, 0, 0}};  // in view, behind, far to the side
  Camera camera;
  camera.look_at({0, 0, 5}, {0, 0, 0});
  auto pipelines = splats::create_splat_pipelines(*ctx, WGPUTextureFormat_RGBA8Unorm);
  auto gpu_splats = splats::upload_splats(*ctx, set);
  Target target = make_target(*ctx, 64, 64, glm::dvec3(0.0), 0.0f);
  splats::draw_splats(*ctx, pipelines, gpu_splats, camera, target.color.get(),
                      target.color_view.get(), 64, 64);
  EXPECT_EQ(splats::read_visible_count(*ctx, gpu_splats), 1u);
}

// Points and splats in one frame: a wall of red points at z = 0 over the left half of the view;
// an opaque green splat in front of it, a blue one behind it (hidden), and a yellow one behind
// the wall's plane but beside the wall (seen). Naive points (their exact depth) and the
// default blended splatting (its pre-pass depth, pushed back by 1%) and the compute rasterizer
// (its depth buffer exported as a depth texture).
enum class PointPath { Naive, Blend, Compute };
class SplatsWithPoints : public ::testing::TestWithParam<std::tuple<std::string, PointPath>> {};

TEST_P(SplatsWithPoints, OccludeEachOther) {
  // Not a structured binding: the lambdas below capture it (clang 14 cannot capture those).
  const auto backend = std::get<0>(GetParam());
  const auto path = std::get<1>(GetParam());
  gpu::ContextOptions options;
  options.backend = backend;
  auto ctx = gpu::create_context(options);
  const uint32_t w = 160, h = 120;

  pc::PointCloud cloud;
  pc::PointChunk chunk;
  for (int iy = 0; iy <= 80; ++iy)
    for (int ix = 0; ix <= 60; ++ix) {
      const float x = -3.0f + 0.05f * float(ix), y = -2.0f + 0.05f * float(iy);
      chunk.vertices.push_back({x, y, 0.0f, 0xff0000ffu, 0u});
      chunk.bounds.extend(glm::dvec3(x, y, 0.0));
    }
  chunk.spacing = 0.05;
  cloud.world_bounds = chunk.bounds;
  cloud.point_count = chunk.vertices.size();
  cloud.attributes.has_rgb = true;
  cloud.chunks.push_back(std::move(chunk));
  auto gpu_cloud = pc::upload_point_cloud(*ctx, cloud);
  std::unique_ptr<pc::GpuBatchedCloud> batched;
  std::unique_ptr<pc::ComputeRasterPipeline> raster;
  if (path == PointPath::Compute) {
    batched = std::make_unique<pc::GpuBatchedCloud>(
        pc::upload_batched_cloud(*ctx, pc::build_batches(cloud)));
    raster = std::make_unique<pc::ComputeRasterPipeline>(
        pc::create_compute_raster_pipeline(*ctx, WGPUTextureFormat_RGBA8Unorm));
  }
  auto point_pipelines = pc::create_point_pipelines(*ctx, WGPUTextureFormat_RGBA8Unorm);
  pc::PointRenderSettings settings;
  settings.color = pc::ColorMode::Rgb;
  settings.splat = path == PointPath::Blend ? pc::SplatMode::Blend : pc::SplatMode::Naive;
  settings.edl = false;
  settings.point_size = 6.0f;
  settings.background = {0.0f, 0.0f, 0.0f};

  // SH degree 0: DC = (colour - 0.5) / C0.
  io::SplatSet set;
  auto add = [&](glm::vec3 p, glm::vec3 color) {
    set.positions.push_back(p);
    set.scales.push_back({0.12f, 0.12f, 0.12f});
    set.rotations.push_back({0, 0, 0, 1});
    set.opacities.push_back(1.0f);
    set.sh_dc.push_back((color - 0.5f) / float(kSH0));
  };
  add({-1.5f, 0.8f, 1.0f}, {0, 1, 0});    // in front of the wall
  add({-1.5f, -0.8f, -1.0f}, {0, 0, 1});  // behind the wall
  add({1.5f, 0.0f, -1.0f}, {1, 1, 0});    // behind the wall's plane, beside the wall
  auto gpu_splats = splats::upload_splats(*ctx, set);
  auto splat_pipelines = splats::create_splat_pipelines(*ctx, WGPUTextureFormat_RGBA8Unorm);

  Camera camera;
  camera.look_at({0, 0, 6}, {0, 0, 0});
  auto render = [&](bool depth_test,
                    splats::SplatRasterizer rasterizer = splats::SplatRasterizer::Quads) {
    auto color = gpu::create_texture_2d(
        *ctx, w, h, WGPUTextureFormat_RGBA8Unorm,
        WGPUTextureUsage_RenderAttachment | WGPUTextureUsage_CopySrc, "test-color");
    auto view = gpu::create_view(color);
    gpu::RenderGraph graph;
    graph.import_texture("color", color.get(), view.get(),
                         {w, h, WGPUTextureFormat_RGBA8Unorm, WGPUTextureUsage_RenderAttachment},
                         gpu::Access::Writable);
    if (path == PointPath::Compute) {
      pc::ComputeRasterOptions options;
      options.point_size = 6.0f;
      options.background = {0.0f, 0.0f, 0.0f};
      options.depth_texture = "depth";
      pc::add_compute_raster_passes(graph, *raster, *batched, camera, options, w, h);
    } else {
      pc::PointPassTargets point_targets;
      point_targets.keep_depth = true;
      pc::add_point_cloud_passes(graph, point_pipelines, gpu_cloud, camera, settings, w, h,
                                 point_targets);
    }
    splats::SplatPassTargets splat_targets;
    if (!depth_test) splat_targets.depth.clear();
    splat_targets.rasterizer = rasterizer;
    splats::add_splat_passes(graph, splat_pipelines, gpu_splats, camera, w, h, splat_targets);
    graph.execute(*ctx, point_pipelines.pool);
    ctx->check("points and splats");
    return gpu::read_texture(*ctx, color.get(), w, h, WGPUTextureFormat_RGBA8Unorm);
  };
  // Where each splat's centre lands.
  const glm::dmat4 vp = camera.view_projection(double(w) / h);
  auto pixel = [&](const gpu::Image& image, glm::vec3 p) {
    glm::dvec4 c = vp * glm::dvec4(glm::dvec3(p), 1.0);
    const int x = int((c.x / c.w * 0.5 + 0.5) * w), y = int((0.5 - c.y / c.w * 0.5) * h);
    const uint8_t* px = &image.rgba[(size_t(y) * w + size_t(x)) * 4];
    return glm::ivec3(px[0], px[1], px[2]);
  };
  for (auto rasterizer : {splats::SplatRasterizer::Quads, splats::SplatRasterizer::Tiles}) {
    SCOPED_TRACE(rasterizer == splats::SplatRasterizer::Quads ? "quads" : "tiles");
    const gpu::Image tested = render(true, rasterizer);
    const glm::ivec3 front = pixel(tested, set.positions[0]);
    const glm::ivec3 behind = pixel(tested, set.positions[1]);
    const glm::ivec3 beside = pixel(tested, set.positions[2]);
    EXPECT_GT(front.g, 200) << "the splat in front of the points shows";
    EXPECT_LT(front.r, 60);
    EXPECT_GT(behind.r, 200) << "the points hide the splat behind them";
    EXPECT_LT(behind.b, 60);
    EXPECT_GT(beside.r, 200);
    EXPECT_GT(beside.g, 200) << "a splat behind the points' plane but not behind a point shows";
    // Without the depth test the hidden splat would show: the test above can fail.
    const gpu::Image untested = render(false, rasterizer);
    EXPECT_GT(pixel(untested, set.positions[1]).b, 200);
  }
}

INSTANTIATE_TEST_SUITE_P(Backends, SplatsWithPoints,
                         ::testing::Combine(::testing::Values("dawn", "wgpu"),
                                            ::testing::Values(PointPath::Naive, PointPath::Blend,
                                                              PointPath::Compute)),
                         [](const auto& info) {
                           const PointPath path = std::get<1>(info.param);
                           return std::get<0>(info.param) + (path == PointPath::Naive ? "_naive"
                                                             : path == PointPath::Blend
                                                                 ? "_blend"
                                                                 : "_compute");
                         });

INSTANTIATE_TEST_SUITE_P(Backends, Splats, ::testing::Values("dawn", "wgpu"),
                         [](const auto& info) { return info.param; });

}  // namespace
