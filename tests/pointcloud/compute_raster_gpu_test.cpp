// The compute rasterizer on lavapipe, for both WebGPU implementations. wgpu-native has 64-bit
// atomics (visibility buffer); Dawn runs the 32-bit two-pass fallback.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>

#include "stipple/io/las.hpp"
#include "stipple/io/procedural.hpp"
#include "stipple/pointcloud/batches.hpp"
#include "stipple/pointcloud/compute_raster.hpp"
#include "stipple/pointcloud/filters.hpp"
#include "stipple/pointcloud/point_cloud.hpp"
#include "stipple/pointcloud/point_renderer.hpp"
#include "stipple/renderer/gpu.hpp"
#include "test_util.hpp"

using namespace stipple;

namespace {

class ComputeRaster : public ::testing::TestWithParam<std::string> {
 protected:
  std::unique_ptr<gpu::Context> context() {
    gpu::ContextOptions options;
    options.backend = GetParam();
    options.optional_features = pc::compute_raster_features();
    return gpu::create_context(options);
  }
};

const uint8_t kBlack[3] = {0, 0, 0};

struct Rendered {
  gpu::Image image;
  pc::RasterCounters counters;
  bool visibility64 = false;
};

Rendered render_uploaded(gpu::Context& ctx, pc::GpuBatchedCloud& gpu_cloud, const Camera& camera,
                         pc::ComputeRasterOptions options, uint32_t w, uint32_t h,
                         bool force_fallback = false,
                         pc::DisplayPass display = pc::DisplayPass::Auto,
                         const pc::RasterKernel& kernel = {});

Rendered render_compute(gpu::Context& ctx, const pc::BatchedCloud& cloud, const Camera& camera,
                        pc::ComputeRasterOptions options, uint32_t w, uint32_t h,
                        bool force_fallback = false, uint64_t max_segment_points = 0,
                        pc::DisplayPass display = pc::DisplayPass::Auto,
                        const pc::RasterKernel& kernel = {}) {
  auto gpu_cloud = pc::upload_batched_cloud(ctx, cloud, {max_segment_points});
  return render_uploaded(ctx, gpu_cloud, camera, options, w, h, force_fallback, display, kernel);
}

Rendered render_uploaded(gpu::Context& ctx, pc::GpuBatchedCloud& gpu_cloud, const Camera& camera,
                         pc::ComputeRasterOptions options, uint32_t w, uint32_t h,
                         bool force_fallback, pc::DisplayPass display,
                         const pc::RasterKernel& kernel) {
  auto target = gpu::create_offscreen_target(ctx, w, h);
  auto pipeline =
      pc::create_compute_raster_pipeline(ctx, target.color_format, force_fallback, display, kernel);
  options.background = {0, 0, 0};
  options.storage_target = true;
  gpu::RenderGraph graph;
  graph.import_texture("color", target.color.get(), target.color_view.get(),
                       {w, h, target.color_format,
                        WGPUTextureUsage_RenderAttachment | WGPUTextureUsage_StorageBinding},
                       gpu::Access::Writable);
  pc::add_compute_raster_passes(graph, pipeline, gpu_cloud, camera, options, w, h);
  gpu::TransientPool pool;
  graph.execute(ctx, pool);
  Rendered r;
  r.image = gpu::read_texture(ctx, target.color.get(), w, h, target.color_format);
  r.counters = pc::read_raster_counters(ctx, pipeline);
  r.visibility64 = pipeline.visibility64;
  ctx.check("compute raster test");
  return r;
}

// The billboard path at its plainest: 1-pixel squares (or round splats of a larger size),
// depth-tested, no EDL, black background; colour from `style` (RGB by default).
gpu::Image render_billboard(gpu::Context& ctx, const pc::PointCloud& cloud, const Camera& camera,
                            uint32_t w, uint32_t h, pc::PointRenderSettings style = {}) {
  auto gpu_cloud = pc::upload_point_cloud(ctx, cloud);
  auto target = gpu::create_offscreen_target(ctx, w, h);
  auto pipelines = pc::create_point_pipelines(ctx, target.color_format);
  if (style.color == pc::ColorMode::Auto) style.color = pc::ColorMode::Rgb;
  if (style.point_size <= 1.0f) {  // 1-pixel squares; larger sizes keep their round splats
    style.point_size = 1.0f;
    style.round = false;
  }
  style.splat = pc::SplatMode::Naive;
  style.edl = false;
  style.background = {0, 0, 0};
  pc::draw_points(ctx, pipelines, gpu_cloud, camera, style, target.color.get(),
                  target.color_view.get(), w, h);
  return gpu::read_texture(ctx, target.color.get(), w, h, target.color_format);
}

// A file loaded whole, framed at w x h, and its batches (Morton order, RGB).
struct Framed {
  pc::PointCloud cloud;
  Camera camera;
  pc::BatchedCloud batched;
};
Framed load_framed(const std::filesystem::path& path, uint32_t w, uint32_t h) {
  pc::LoadOptions load;
  load.progress = false;
  Framed f;
  f.cloud = pc::load_point_cloud({path}, load);
  f.camera = frame_box(f.cloud.world_bounds, double(w) / h);
  f.batched = pc::build_batches(f.cloud);
  return f;
}

// The kernel choices besides the default (compute_raster.hpp, RasterKernel): the fallback's
// winner events where the adapter would not take them (Dawn's fallback on lavapipe; the 64-bit
// path ignores them).
std::vector<std::pair<std::string, pc::RasterKernel>> kernel_variants() {
  pc::RasterKernel events;
  events.fallback_events = pc::AutoSwitch::On;
  return {{"winner events instead of the fallback's colour pass", events}};
}

void expect_similar(const gpu::Image& a, const gpu::Image& b, double coverage_tol, double mean_tol,
                    const char* what) {
  auto sa = test::coverage_stats(a, kBlack, 0), sb = test::coverage_stats(b, kBlack, 0);
  ASSERT_GT(sa.coverage, 0.01) << what;
  std::printf("%s: coverage %.4f vs %.4f, mean (%.1f %.1f %.1f) vs (%.1f %.1f %.1f)\n", what,
              sa.coverage, sb.coverage, sa.mean[0], sa.mean[1], sa.mean[2], sb.mean[0], sb.mean[1],
              sb.mean[2]);
  EXPECT_NEAR(sb.coverage / sa.coverage, 1.0, coverage_tol) << what;
  for (int c = 0; c < 3; ++c) EXPECT_NEAR(sb.mean[c], sa.mean[c], mean_tol) << what << " ch " << c;
}

}  // namespace

TEST_P(ComputeRaster, BackendPicksVisibilityBufferOrFallback) {
  auto ctx = context();
  // wgpu-native on lavapipe has 64-bit atomics; Dawn (bun-webgpu 0.1.7) has none.
  EXPECT_EQ(pc::has_visibility64(*ctx), GetParam() == "wgpu");
}

TEST_P(ComputeRaster, AgreesWithBillboardsOnAutzen) {
  STIPPLE_REQUIRE_DATA(path, "las/autzen_trim.las");
  auto ctx = context();
  const uint32_t w = 640, h = 360;
  const auto [cloud, camera, batched] = load_framed(path, w, h);
  auto billboard = render_billboard(*ctx, cloud, camera, w, h);
  auto compute = render_compute(*ctx, batched, camera, {}, w, h);
  EXPECT_EQ(compute.visibility64, GetParam() == "wgpu");
  // Both draw every point into the one pixel it projects to; they differ in which point wins
  // a pixel (nearest by depth buffer vs visibility buffer, 10-bit positions for small batches)
  // and at pixel edges: coverage within 1 % (measured: equal to 4 digits), mean colour within
  // 1.5 levels (measured: 0.1), fewer than 10 % of pixels off by more than 8 levels.
  expect_similar(billboard, compute.image, 0.01, 1.5, "compute vs billboard");
  EXPECT_LT(test::differing_fraction(billboard, compute.image, 8), 0.10);
}

// Every colour mode: the compute path shades the visible points from their RGB and attribute
// words as the billboard shaders do (point_colors.wgsl is shared), so the images agree as
// closely as in RGB. One batching serves every mode: the mode is a per-frame uniform.
TEST_P(ComputeRaster, ColourModesMatchTheBillboardPath) {
  // The generated scene has RGB, intensity, classes (ground, buildings, vegetation) and
  // several returns.
  const auto path =
      std::filesystem::temp_directory_path() / ("stipple_colour_modes_" + GetParam() + ".las");
  if (!std::filesystem::exists(path)) {
    const std::string generate =
        std::string(STIPPLE_BINARY) + " generate -n 200000 -o " + path.string() + " >/dev/null";
    ASSERT_EQ(std::system(generate.c_str()), 0);
  }
  auto ctx = context();
  pc::LoadOptions load;
  load.progress = false;
  auto cloud = pc::load_point_cloud({path}, load);
  const uint32_t w = 480, h = 270;
  Camera camera = frame_box(cloud.world_bounds, double(w) / h);
  const auto batched = pc::build_batches(cloud);
  for (pc::ColorMode mode :
       {pc::ColorMode::Elevation, pc::ColorMode::Intensity, pc::ColorMode::Classification,
        pc::ColorMode::ReturnNumber, pc::ColorMode::Constant}) {
    pc::PointRenderSettings settings;
    settings.color = mode;
    settings.constant_color = {0.9f, 0.4f, 0.2f};
    pc::ComputeRasterOptions options;
    options.shading = pc::point_shading(settings, cloud.attributes);
    // The billboard reference with the same ramps and constant colour.
    auto billboard = render_billboard(*ctx, cloud, camera, w, h, settings);
    auto compute = render_compute(*ctx, batched, camera, options, w, h);
    const std::string what = std::string("colour mode ") + pc::color_mode_name(mode);
    // The same bounds as RGB: coverage within 1 %, mean within 1.5 levels, and fewer than 10 %
    // of the pixels off by more than 8 levels (which point wins a pixel differs).
    expect_similar(billboard, compute.image, 0.01, 1.5, what.c_str());
    EXPECT_LT(test::differing_fraction(billboard, compute.image, 8), 0.10) << what;
  }
}

// Points larger than a pixel: the compute path dilates each drawn pixel to a disc of the point
// size, the nearest disc winning, as the billboard path's depth-tested round splats do.
TEST_P(ComputeRaster, LargePointsMatchRoundSplats) {
  STIPPLE_REQUIRE_DATA(path, "las/autzen_trim.las");
  auto ctx = context();
  const uint32_t w = 640, h = 360;
  const auto [cloud, camera, batched] = load_framed(path, w, h);
  const auto one = render_compute(*ctx, batched, camera, {}, w, h);
  for (float size : {3.0f, 5.0f}) {
    pc::PointRenderSettings style;
    style.point_size = size;
    style.round = true;
    auto billboard = render_billboard(*ctx, cloud, camera, w, h, style);
    pc::ComputeRasterOptions options;
    options.point_size = size;
    auto compute = render_compute(*ctx, batched, camera, options, w, h);
    const std::string what = std::to_string(int(size)) + " px";
    // Coverage within 8 % (discs of the offsets within size/2 against rasterized circles) and
    // the mean colour within 3 levels.
    expect_similar(billboard, compute.image, 0.08, 3.0, what.c_str());
    // Larger than 1-pixel points: the surface is closed at 1 px already here (coverage 0.124),
    // so the discs grow it at the edges and in gaps (measured 0.144 at 3 px).
    EXPECT_GT(test::coverage_stats(compute.image, kBlack, 0).coverage,
              1.1 * test::coverage_stats(one.image, kBlack, 0).coverage)
        << what;
  }
}

TEST_P(ComputeRaster, CountersMatchCpuReference) {
  auto ctx = context();
  io::SceneParams scene;
  scene.point_count = 400'000;
  auto batched = pc::generate_batched_scene(scene, pc::SpatialOrder::Morton);
  const uint32_t w = 320, h = 180;
  // Low over the scene, looking across it: some batches behind, some beside, some far.
  Aabb box = io::scene_bounds(scene);
  glm::dvec3 c = box.center();
  Camera camera;
  camera.fov_y = glm::radians(50.0);
  camera.look_at(z_up_to_y_up({c.x - 20, c.y - 30, c.z + 30}),
                 z_up_to_y_up({c.x + 60, c.y + 80, c.z - 40}));
  camera.near_plane = 0.5;
  // The LOD threshold: the median projected size of the visible batches, so about half go.
  std::vector<float> sizes;
  glm::mat4 vp = pc::raster_view_proj(camera, w, h);
  for (const auto& b : batched.batches) {
    auto v = pc::classify_batch(vp, glm::vec3(b.min - camera.position), glm::vec3(b.size), {w, h});
    if (v.visible) sizes.push_back(v.size_px);
  }
  ASSERT_FALSE(sizes.empty());
  std::sort(sizes.begin(), sizes.end());
  for (float min_px : {0.0f, sizes[sizes.size() / 2]}) {
    pc::ComputeRasterOptions options;
    options.min_batch_px = min_px;
    auto r = render_compute(*ctx, batched, camera, options, w, h);
    pc::CullSettings s{w, h, min_px, 0};
    auto ref = pc::reference_counters(batched.batches, camera, s);
    EXPECT_EQ(r.counters.batches_processed, batched.batches.size());
    EXPECT_EQ(r.counters.batches_processed, ref.batches_processed);
    EXPECT_GT(ref.batches_culled, 0u);
    EXPECT_GT(ref.batches_rendered, 0u);
    if (min_px > 0) {
      EXPECT_GT(ref.batches_lod_skipped, 0u);
    }
    EXPECT_EQ(r.counters.batches_rendered, ref.batches_rendered) << min_px;
    EXPECT_EQ(r.counters.batches_culled, ref.batches_culled) << min_px;
    EXPECT_EQ(r.counters.batches_lod_skipped, ref.batches_lod_skipped) << min_px;
    EXPECT_EQ(r.counters.points_rendered, ref.points_rendered) << min_px;
    for (int k = 0; k < 3; ++k) {
      EXPECT_EQ(r.counters.batches_by_bits[k], ref.batches_by_bits[k]) << min_px << " " << k;
      EXPECT_EQ(r.counters.points_by_bits[k], ref.points_by_bits[k]) << min_px << " " << k;
    }
  }
}

// More batches than one dispatch dimension holds (65,535): they go in rows of workgroups, and
// every batch is still processed exactly once.
TEST_P(ComputeRaster, MoreBatchesThanOneDispatchRow) {
  auto ctx = context();
  io::SceneParams scene;
  scene.point_count = 300'000;
  auto batched = pc::generate_batched_scene(scene, pc::SpatialOrder::Hilbert, 4);
  ASSERT_GT(batched.batches.size(), 70'000u);
  const uint32_t w = 320, h = 180;
  Camera camera = frame_box(batched.world_bounds, double(w) / h);
  auto r = render_compute(*ctx, batched, camera, {}, w, h);
  auto ref = pc::reference_counters(batched.batches, camera, {w, h});
  EXPECT_EQ(r.counters.batches_processed, batched.batches.size());
  EXPECT_EQ(r.counters.batches_rendered, ref.batches_rendered);
  EXPECT_EQ(r.counters.points_rendered, ref.points_rendered);
  EXPECT_EQ(r.counters.points_rendered, 300'000u);
  EXPECT_GT(test::coverage_stats(r.image, kBlack, 0).coverage, 0.05);
}

// A loaded cloud batched and uploaded a group of chunks at a time (upload_batched_chunks: how
// the page holds 136M points in wasm32's 4 GB) draws every point, and the image of the whole
// build up to quantization: the batches differ (each group sorted on its own), so do their
// boxes, and a point's position is quantized in its batch's box (10 bits an axis where the batch
// is small on screen). Measured: 2.6% of the pixels differ at all, 0.1% by more than 48.
TEST_P(ComputeRaster, ChunkGroupsDrawAsTheWholeBuild) {
  auto ctx = context();
  io::SceneParams scene;
  scene.point_count = 400'000;
  const pc::PointCloud cloud = pc::generate_scene_cloud(scene, 50'000);
  ASSERT_EQ(cloud.chunks.size(), 8u);
  auto whole = pc::upload_batched_cloud(*ctx, pc::build_batches(cloud));
  auto grouped = pc::upload_batched_chunks(*ctx, cloud, 100'000);  // four groups of two chunks
  ASSERT_EQ(grouped.segments.size(), 1u);
  EXPECT_EQ(grouped.point_count, 400'000u);
  uint64_t batched = 0;
  for (size_t b = 0; b < grouped.batches.size(); ++b) {
    EXPECT_EQ(grouped.batches[b].first, batched) << "batch " << b;
    batched += grouped.batches[b].count;
  }
  EXPECT_EQ(batched, 400'000u);
  const uint32_t w = 320, h = 180;
  Camera camera = frame_box(cloud.world_bounds, double(w) / h);
  auto a = render_uploaded(*ctx, whole, camera, {}, w, h);
  auto b = render_uploaded(*ctx, grouped, camera, {}, w, h);
  EXPECT_EQ(b.counters.points_rendered, 400'000u);
  EXPECT_GT(test::coverage_stats(a.image, kBlack, 0).coverage, 0.05);
  const double covered_a = test::coverage_stats(a.image, kBlack, 0).coverage;
  EXPECT_NEAR(test::coverage_stats(b.image, kBlack, 0).coverage, covered_a, 0.01 * covered_a);
  EXPECT_LE(test::differing_fraction(a.image, b.image, 48), 0.01);
  // Under two groups: the whole build, batch for batch.
  auto small = pc::upload_batched_chunks(*ctx, cloud, 300'000);
  EXPECT_EQ(small.batches.size(), whole.batches.size());
}

// Eye-dome lighting in the display pass: no pixel covered anew, none brighter, pixels behind
// nearer neighbours darker, and more of them the stronger it is (1-pixel points of a sparse
// scan have many such neighbours, so the share is large; without EDL it is zero).
TEST_P(ComputeRaster, EyeDomeLightingDarkensBehindNearerNeighbours) {
  auto ctx = context();
  io::SceneParams scene;
  scene.point_count = 1'000'000;
  auto batched = pc::generate_batched_scene(scene, pc::SpatialOrder::Hilbert);
  const uint32_t w = 160, h = 90;
  Camera camera = frame_box(batched.world_bounds, double(w) / h, 30.0, 80.0, 40.0);
  auto plain = render_compute(*ctx, batched, camera, {}, w, h);
  auto darkened_share = [&](float strength) {
    pc::ComputeRasterOptions edl;
    edl.edl_strength = strength;
    edl.edl_radius = 1.4f;
    auto b = render_compute(*ctx, batched, camera, edl, w, h);
    uint64_t covered = 0, darker = 0;
    for (size_t i = 0; i < plain.image.rgba.size(); i += 4) {
      const auto* pa = &plain.image.rgba[i];
      const auto* pb = &b.image.rgba[i];
      if (!(pa[0] | pa[1] | pa[2])) {  // background stays background
        EXPECT_FALSE(pb[0] | pb[1] | pb[2]) << "pixel " << i / 4;
        continue;
      }
      ++covered;
      int most = 0;
      for (int c = 0; c < 3; ++c) {
        EXPECT_LE(int(pb[c]), int(pa[c]) + 1) << "pixel " << i / 4;  // never brighter
        most = std::max(most, int(pa[c]) - int(pb[c]));
      }
      if (most > 8) ++darker;
    }
    EXPECT_GT(covered, 1000u);
    return double(darker) / double(std::max<uint64_t>(covered, 1));
  };
  const double weak = darkened_share(5.0f), strong = darkened_share(60.0f);
  std::printf("EDL darkened %.1f%% (strength 5) and %.1f%% (60) of the covered pixels\n",
              100 * weak, 100 * strong);
  EXPECT_GT(weak, 0.01);
  EXPECT_GT(strong, weak + 0.05);
  EXPECT_LT(strong, 0.9);
}

// The display as a compute pass writing a storage texture gives the render pass's image, bit
// for bit (tolerance 0), with EDL and with hole filling.
TEST_P(ComputeRaster, DisplayAsComputePassMatchesTheRenderPass) {
  auto ctx = context();
  io::SceneParams scene;
  scene.point_count = 300'000;
  auto batched = pc::generate_batched_scene(scene, pc::SpatialOrder::Hilbert);
  const uint32_t w = 203, h = 117;  // not multiples of the 16 x 16 workgroups
  Camera camera = frame_box(batched.world_bounds, double(w) / h, 30.0, 60.0, 40.0);
  pc::ComputeRasterOptions options;
  options.edl_strength = 60.0f;
  options.edl_radius = 1.4f;
  options.fill_radius = 1;
  auto by_render =
      render_compute(*ctx, batched, camera, options, w, h, false, 0, pc::DisplayPass::Render);
  auto by_compute =
      render_compute(*ctx, batched, camera, options, w, h, false, 0, pc::DisplayPass::Compute);
  EXPECT_GT(test::coverage_stats(by_render.image, kBlack, 0).coverage, 0.2);
  EXPECT_EQ(test::differing_fraction(by_render.image, by_compute.image, 0), 0.0);
}

TEST_P(ComputeRaster, PrecisionLevelsAgreeForSmallBatches) {
  auto ctx = context();
  io::SceneParams scene;
  scene.point_count = 300'000;
  auto batched = pc::generate_batched_scene(scene, pc::SpatialOrder::Hilbert);
  const uint32_t w = 320, h = 180;
  Camera camera = frame_box(batched.world_bounds, double(w) / h);
  pc::ComputeRasterOptions options;
  options.force_bits = 30;
  auto full = render_compute(*ctx, batched, camera, options, w, h);
  // Every batch is a few pixels wide here, so 10 bits (1/1024 of a batch) are sub-pixel.
  EXPECT_EQ(full.counters.batches_by_bits[2], full.counters.batches_rendered);
  EXPECT_EQ(pc::reference_counters(batched.batches, camera, {w, h}).batches_by_bits[0],
            full.counters.batches_rendered);
  for (int bits : {10, 20}) {
    options.force_bits = bits;
    auto r = render_compute(*ctx, batched, camera, options, w, h);
    EXPECT_EQ(r.counters.batches_by_bits[bits / 10 - 1], r.counters.batches_rendered);
    auto sf = test::coverage_stats(full.image, kBlack, 0);
    auto sr = test::coverage_stats(r.image, kBlack, 0);
    EXPECT_NEAR(sr.coverage, sf.coverage, 0.002) << bits;
    // Only points within a 1/2048-of-a-batch distance of a pixel edge can move.
    EXPECT_LT(test::differing_fraction(full.image, r.image, 0), 0.02) << bits;
  }
}

TEST_P(ComputeRaster, FallbackMatchesVisibilityBuffer) {
  auto ctx = context();
  io::SceneParams scene;
  scene.point_count = 300'000;
  auto batched = pc::generate_batched_scene(scene, pc::SpatialOrder::Morton);
  const uint32_t w = 320, h = 180;
  Camera camera = frame_box(batched.world_bounds, double(w) / h, 10.0, 25.0);
  auto fallback = render_compute(*ctx, batched, camera, {}, w, h, /*force_fallback=*/true);
  EXPECT_FALSE(fallback.visibility64);
  auto automatic = render_compute(*ctx, batched, camera, {}, w, h);
  if (!automatic.visibility64) GTEST_SKIP() << "no 64-bit atomics: only the fallback runs here";
  // Same nearest depth per pixel; they differ only where several points share it exactly
  // (the fallback averages them, the visibility buffer keeps the lowest index).
  EXPECT_EQ(test::coverage_stats(fallback.image, kBlack, 0).covered,
            test::coverage_stats(automatic.image, kBlack, 0).covered);
  EXPECT_LT(test::differing_fraction(fallback.image, automatic.image, 2), 0.01);
}

// Where a browser offers atomic-vec2u-min-max but its compiler refuses the 64-bit pass, the
// frame is the fallback's (with a warning), not an error: here a device without 64-bit atomics
// is told it has the feature, and its compiler (Dawn's, which lacks the extension) refuses the
// pass. Devices with u64 atomics never try it.
TEST_P(ComputeRaster, ARefusedVec2uPassDrawsWithTheFallback) {
  auto ctx = context();
  if (pc::has_visibility64(*ctx))
    GTEST_SKIP() << "64-bit atomics as u64: the vec2u pass is not tried";
  io::SceneParams scene;
  scene.point_count = 100'000;
  auto batched = pc::generate_batched_scene(scene, pc::SpatialOrder::Morton);
  const uint32_t w = 160, h = 90;
  Camera camera = frame_box(batched.world_bounds, double(w) / h);
  auto plain = render_compute(*ctx, batched, camera, {}, w, h);
  ctx->features.push_back(gpu::kFeatureAtomicVec2uMinMax);
  ASSERT_TRUE(pc::has_visibility64(*ctx));
  auto refused = render_compute(*ctx, batched, camera, {}, w, h);
  EXPECT_FALSE(refused.visibility64);
  EXPECT_FALSE(pc::has_visibility64(*ctx));  // not tried again
  EXPECT_EQ(test::differing_fraction(plain.image, refused.image, 0), 0.0);
  EXPECT_GT(test::coverage_stats(refused.image, kBlack, 0).coverage, 0.05);
}

TEST_P(ComputeRaster, SegmentsAndHqs) {
  auto ctx = context();
  io::SceneParams scene;
  scene.point_count = 200'000;
  auto batched = pc::generate_batched_scene(scene, pc::SpatialOrder::Morton);
  const uint32_t w = 320, h = 180;
  Camera camera = frame_box(batched.world_bounds, double(w) / h);
  auto one = render_compute(*ctx, batched, camera, {}, w, h);
  // Segments of 5 batches: 4 dispatches' worth of buffers, indices offset per segment.
  auto split = render_compute(*ctx, batched, camera, {}, w, h, false, 5 * pc::kBatchPoints);
  EXPECT_EQ(test::differing_fraction(one.image, split.image, 0), 0.0);
  EXPECT_EQ(split.counters.points_rendered, one.counters.points_rendered);
  // High-quality shading averages the points within 1 % of the nearest depth: same coverage,
  // colours blended (different, but close on average).
  pc::ComputeRasterOptions hqs;
  hqs.hqs = true;
  auto blended = render_compute(*ctx, batched, camera, hqs, w, h);
  EXPECT_EQ(test::coverage_stats(blended.image, kBlack, 0).covered,
            test::coverage_stats(one.image, kBlack, 0).covered);
  expect_similar(one.image, blended.image, 0.001, 4.0, "hqs");
  EXPECT_GT(test::differing_fraction(one.image, blended.image, 0), 0.01);
}

// The kernel choices (kernel_variants) change how the colours are found, not the result: the
// nearest point of each pixel, coloured by the resolve pass or by the colour pass (which averages
// exact ties). Tolerance: 0.1 % of the pixels may differ; measured 0.
TEST_P(ComputeRaster, KernelVariantsDrawTheSameImage) {
  STIPPLE_REQUIRE_DATA(path, "las/autzen_trim.las");
  auto ctx = context();
  const uint32_t w = 480, h = 270;
  const auto [cloud, camera, batched] = load_framed(path, w, h);
  const auto reference = render_compute(*ctx, batched, camera, {}, w, h);
  ASSERT_GT(test::coverage_stats(reference.image, kBlack, 0).coverage, 0.05);
  for (const auto& [name, kernel] : kernel_variants()) {
    const auto r =
        render_compute(*ctx, batched, camera, {}, w, h, false, 0, pc::DisplayPass::Auto, kernel);
    const double differ = test::differing_fraction(reference.image, r.image, 0);
    std::printf("%s: %.4f%% of the pixels differ\n", name.c_str(), 100 * differ);
    EXPECT_LE(differ, 0.001) << name;
    EXPECT_EQ(r.counters.points_rendered, reference.counters.points_rendered) << name;
  }
}

// The batch passes shaped for CPU adapters (RasterKernel::cpu_shape: no barrier, each thread
// classifying its batch; HQS's sums through the lean loop without the workgroup tile; the sums
// cleared by clearBuffer; with points larger than a pixel on the scatter's devices, the display
// reading through the dilation's winners) draw what the GPU shape draws: the fallback's colour
// pass, and HQS with 3.5 px points and EDL on the 64-bit and 32-bit depth passes, with the
// display's render and compute forms. Tolerance 0, the same counters.
TEST_P(ComputeRaster, CpuShapedKernelsDrawTheSameImage) {
  STIPPLE_REQUIRE_DATA(path, "las/autzen_trim.las");
  auto ctx = context();
  const uint32_t w = 320, h = 180;
  const auto [cloud, camera, batched] = load_framed(path, w, h);
  pc::RasterKernel gpu_shape, cpu_shape;
  gpu_shape.cpu_shape = pc::AutoSwitch::Off;
  cpu_shape.cpu_shape = pc::AutoSwitch::On;
  pc::ComputeRasterOptions large;  // HQS, dilated (the display through the winners), EDL
  large.hqs = true;
  large.point_size = 3.5f;
  large.edl_strength = 1.0f;
  using Display = pc::DisplayPass;
  const std::tuple<const char*, pc::ComputeRasterOptions, bool, Display> cases[] = {
      {"plain, 32-bit fallback", {}, true, Display::Auto},
      {"HQS, 3.5 px, EDL", large, false, Display::Auto},
      {"HQS, 3.5 px, EDL, 32-bit fallback", large, true, Display::Auto},
      {"HQS, 3.5 px, EDL, the display as a compute pass (the page's)", large, false,
       Display::Compute}};
  for (const auto& [name, options, fallback, display] : cases) {
    SCOPED_TRACE(name);
    const auto a =
        render_compute(*ctx, batched, camera, options, w, h, fallback, 0, display, gpu_shape);
    const auto b =
        render_compute(*ctx, batched, camera, options, w, h, fallback, 0, display, cpu_shape);
    ASSERT_GT(test::coverage_stats(a.image, kBlack, 0).coverage, 0.05);
    EXPECT_EQ(test::differing_fraction(a.image, b.image, 0), 0.0);
    EXPECT_EQ(a.counters.points_rendered, b.counters.points_rendered);
    EXPECT_EQ(a.counters.batches_rendered, b.counters.batches_rendered);
  }
}

// The workgroup tile of HQS's sums takes batches that cover at most 512 pixels: small batches of
// a dense scene at overview distance do. At the plain frame's depth tolerance HQS sums what the
// fallback's colour pass (no tile) sums, the points at each pixel's nearest depth: the images
// are equal (tolerance 0), with the 64-bit visibility buffer's depths and the fallback's.
TEST_P(ComputeRaster, WorkgroupTileDrawsTheSameImage) {
  auto ctx = context();
  io::SceneParams scene;
  scene.point_count = 200'000;
  const pc::PointCloud cloud = pc::generate_scene_cloud(scene);
  const uint32_t w = 320, h = 180;
  const Camera camera = frame_box(cloud.world_bounds, double(w) / h);
  pc::BatchingOptions batching;
  batching.batch_points = 256;  // ~800 batches, most under 512 pixels on screen
  const pc::BatchedCloud batched = pc::build_batches(cloud, batching);
  pc::RasterKernel colour_pass;
  colour_pass.fallback_events = pc::AutoSwitch::Off;
  const auto reference =
      render_compute(*ctx, batched, camera, {}, w, h, true, 0, pc::DisplayPass::Auto, colour_pass);
  ASSERT_GT(test::coverage_stats(reference.image, kBlack, 0).coverage, 0.1);
  pc::ComputeRasterOptions tiled;
  tiled.hqs = true;
  tiled.hqs_tolerance = 1e-6f;  // the plain frame's (add_compute_raster_passes)
  for (bool fallback : {false, true}) {
    SCOPED_TRACE(fallback ? "32-bit fallback" : "64-bit");
    const auto r = render_compute(*ctx, batched, camera, tiled, w, h, fallback);
    EXPECT_EQ(test::differing_fraction(reference.image, r.image, 0), 0.0);
    EXPECT_EQ(r.counters.points_rendered, reference.counters.points_rendered);
  }
}

// The lean loops for 10-bit batches without filters (the depth passes', and the fallback
// colour pass's) give the keys and sums the general loop gives, which draws them where a filter
// is set: a filter that keeps every point (an intensity range of all 16 bits) takes the general
// loops and must draw the same image. From the overview (every batch inside the view: no
// clipping tests) to a camera within the scene (batches cut by the screen's edges and the near
// plane: the lean loop's clipping tests); 64-bit and 32-bit depth passes, plain, with HQS and
// with HQS in the elevation mode (its depth limits come from the lean pass). Tolerance 0.
TEST_P(ComputeRaster, LeanLoopDrawsTheSameImageNearAndFar) {
  auto ctx = context();
  io::SceneParams scene;
  scene.point_count = 300'000;
  const auto batched = pc::generate_batched_scene(scene, pc::SpatialOrder::Morton);
  const uint32_t w = 320, h = 180;
  pc::PointFilter every;
  every.intensity = glm::dvec2(0.0, 65535.0);
  const bool has64 = pc::has_visibility64(*ctx);
  for (const double distance : {1.0, 0.3, 0.02}) {
    Camera camera = frame_box(batched.world_bounds, double(w) / h, 10.0, 25.0);
    const glm::dvec3 centre = batched.world_bounds.center();
    camera.position = centre + (camera.position - centre) * distance;
    for (bool fallback : {false, true}) {
      if (!fallback && !has64) continue;
      for (int mode = 0; mode < 3; ++mode) {  // plain, HQS, HQS by elevation
        SCOPED_TRACE(std::to_string(distance) + (fallback ? ", 32-bit fallback" : ", 64-bit") +
                     (mode == 0   ? ""
                      : mode == 1 ? ", HQS"
                                  : ", HQS by elevation"));
        pc::ComputeRasterOptions options;
        options.hqs = mode > 0;
        if (mode == 2) {
          options.shading = pc::PointShading{pc::ColorMode::Elevation};
          options.shading.elevation_range = {batched.world_bounds.min.y,
                                             batched.world_bounds.max.y};
        }
        pc::ComputeRasterOptions general = options;
        general.filter = every;
        const auto reference = render_compute(*ctx, batched, camera, general, w, h, fallback);
        ASSERT_GT(test::coverage_stats(reference.image, kBlack, 0).coverage, 0.05);
        // The lean loop takes the 10-bit batches: there must be some at every distance.
        ASSERT_GT(reference.counters.batches_by_bits[0], 0u);
        const auto r = render_compute(*ctx, batched, camera, options, w, h, fallback);
        EXPECT_EQ(test::differing_fraction(reference.image, r.image, 0), 0.0);
        EXPECT_EQ(r.counters.points_rendered, reference.counters.points_rendered);
      }
    }
  }
}

// The fallback's winner events (RasterKernel::fallback_events): the depth pass lists the points
// that lowered or tied their pixel's depth, raster-events keeps those at the final depth with the
// lowest index, and the resolve pass colours them: the 64-bit key's choice, so where the device
// has 64-bit atomics the images are equal (tolerance 0), near and far, in RGB, by elevation and
// with a class hidden, in one segment or several. Without 64-bit atomics (Dawn) they are compared
// with the colour pass, which averages exact ties: same coverage, under 1 % of the pixels
// differing by more than 2. Too small a list overflows, and then the colour pass runs: the plain
// fallback's image exactly.
TEST_P(ComputeRaster, FallbackEventsDrawTheVisibilityBuffersImage) {
  auto ctx = context();
  io::SceneParams scene;
  scene.point_count = 300'000;
  const auto batched = pc::generate_batched_scene(scene, pc::SpatialOrder::Morton);
  const uint32_t w = 320, h = 180;
  const bool has64 = pc::has_visibility64(*ctx);
  pc::RasterKernel events;
  events.fallback_events = pc::AutoSwitch::On;
  for (const double distance : {1.0, 0.3, 0.02}) {
    Camera camera = frame_box(batched.world_bounds, double(w) / h, 10.0, 25.0);
    const glm::dvec3 centre = batched.world_bounds.center();
    camera.position = centre + (camera.position - centre) * distance;
    for (int mode = 0; mode < 3; ++mode) {  // RGB, elevation, ground hidden
      SCOPED_TRACE(std::to_string(distance) + (mode == 0   ? ", RGB"
                                               : mode == 1 ? ", elevation"
                                                           : ", ground hidden"));
      pc::ComputeRasterOptions options;
      if (mode == 1) {
        options.shading = pc::PointShading{pc::ColorMode::Elevation};
        options.shading.elevation_range = {batched.world_bounds.min.y, batched.world_bounds.max.y};
      }
      if (mode == 2) options.filter.set_class(2, false);
      const auto ev = render_compute(*ctx, batched, camera, options, w, h, true, 0,
                                     pc::DisplayPass::Auto, events);
      const auto covered = test::coverage_stats(ev.image, kBlack, 0).covered;
      ASSERT_GT(covered, w * h / 20);
      EXPECT_FALSE(ev.counters.events_overflowed);
      EXPECT_GE(ev.counters.events, covered);  // at least the nearest point of each pixel
      const auto split = render_compute(*ctx, batched, camera, options, w, h, true,
                                        5 * pc::kBatchPoints, pc::DisplayPass::Auto, events);
      EXPECT_EQ(test::differing_fraction(ev.image, split.image, 0), 0.0) << "segments";
      const auto colour_pass = render_compute(*ctx, batched, camera, options, w, h, true);
      EXPECT_EQ(test::coverage_stats(colour_pass.image, kBlack, 0).covered, covered);
      EXPECT_EQ(ev.counters.points_rendered, colour_pass.counters.points_rendered);
      if (has64) {
        const auto key64 = render_compute(*ctx, batched, camera, options, w, h);
        EXPECT_EQ(test::differing_fraction(key64.image, ev.image, 0), 0.0) << "64-bit";
      } else {
        EXPECT_LT(test::differing_fraction(colour_pass.image, ev.image, 2), 0.01);
      }
      if (distance == 1.0 && mode == 0) {
        // One slot a pixel: fewer than the overview's events (several a pixel).
        pc::RasterKernel small = events;
        small.events_per_pixel = 1;
        const auto over = render_compute(*ctx, batched, camera, options, w, h, true, 0,
                                         pc::DisplayPass::Auto, small);
        ASSERT_TRUE(over.counters.events_overflowed) << over.counters.events << " events";
        EXPECT_EQ(test::differing_fraction(colour_pass.image, over.image, 0), 0.0) << "overflow";
      }
    }
  }
}

// HQS sums 1,000 points of different colours in one pixel, at one depth, over a plane of one
// point a pixel (more points than the seed's packed 64-bit sums hold, 255): the pixel shows
// their mean.
TEST_P(ComputeRaster, HqsSumsAThousandPointsInOnePixel) {
  auto ctx = context();
  std::vector<glm::dvec3> positions;
  std::vector<uint32_t> colors;
  const uint32_t w = 64, h = 64;
  for (int y = 0; y < 64; ++y)
    for (int x = 0; x < 64; ++x) {  // a plane at z = -100, filling the view
      positions.push_back({(x - 31.5) * 2.5, (y - 31.5) * 2.5, -100.0});
      colors.push_back(pc::pack_rgba(40, 40, 40));
    }
  double r = 0, g = 0, b = 0;
  for (int i = 0; i < 1000; ++i) {  // a cluster far smaller than a pixel, in front of the plane
    positions.push_back({0.01 + 1e-5 * (i % 10), 0.01 + 1e-5 * (i / 10 % 10), -50.0});
    const uint8_t cr = uint8_t(i * 7 % 256), cg = uint8_t(255 - i % 200), cb = uint8_t(i % 3 * 100);
    colors.push_back(pc::pack_rgba(cr, cg, cb));
    r += cr;
    g += cg;
    b += cb;
  }
  pc::BatchedCloud batched;
  pc::append_batches(batched, positions, colors, pc::SpatialOrder::Morton, 512);
  Camera camera;
  camera.fov_y = glm::radians(90.0);
  camera.look_at({0, 0, 0}, {0, 0, -1});
  pc::ComputeRasterOptions options;
  options.hqs = true;
  const auto hqs = render_compute(*ctx, batched, camera, options, w, h);
  // The cluster's pixel: the mean of its 1,000 colours (within rounding to 8 bits).
  const uint32_t px = w / 2, py = h / 2 - 1;  // +y is up on screen: the pixel above the centre
  bool found = false;
  for (uint32_t y = py - 1; y <= py + 2 && !found; ++y)
    for (uint32_t x = px - 1; x <= px + 1 && !found; ++x) {
      const uint8_t* p = &hqs.image.rgba[(size_t(y) * w + x) * 4];
      if (std::abs(p[0] - r / 1000) <= 1 && std::abs(p[1] - g / 1000) <= 1 &&
          std::abs(p[2] - b / 1000) <= 1)
        found = true;
    }
  EXPECT_TRUE(found) << "no pixel near the centre shows the mean colour (" << r / 1000 << ", "
                     << g / 1000 << ", " << b / 1000 << ")";
}

// Filters and clip regions hold in every kernel variant (the default, and the fallback's winner
// events where the adapter has no 64-bit atomics), with and without HQS: the GPU's filter draws
// what the cloud kept by the CPU's test (chunk_point_shown) draws unfiltered. Buildings hidden
// inside a rotated box, in every variant; first returns outside a polygon with a hole, in the
// default one (the variants share the filter).
// Tolerance: 0.5% of the pixels (the kept cloud is batched anew: other boxes, other
// quantization); measured at most 0.12% on both backends. Dawn always accumulates (no 64-bit
// atomics), so HQS adds nothing there. Highlight keeps the coverage and tints the pixels whose
// nearest point is in the box, in every variant alike.
TEST_P(ComputeRaster, FiltersAndClipsHoldInEveryKernelVariant) {
  auto ctx = context();
  io::SceneParams scene;
  scene.point_count = 100'000;
  const pc::PointCloud cloud = pc::generate_scene_cloud(scene);
  const uint32_t w = 320, h = 180;
  const Camera camera = frame_box(cloud.world_bounds, double(w) / h);
  // The scene's extent in source coordinates (Z up).
  const glm::dvec3 a = y_up_to_z_up(cloud.world_bounds.min),
                   b = y_up_to_z_up(cloud.world_bounds.max);
  const glm::dvec3 lo = glm::min(a, b), hi = glm::max(a, b), mid = (lo + hi) * 0.5, size = hi - lo;

  struct Case {
    std::string name;
    pc::PointFilter filter;
    pc::ClipRegion clip;
  };
  std::vector<Case> cases(2);
  cases[0].name = "no buildings, rotated box";
  cases[0].filter.set_class(6, false);
  cases[0].clip.boxes.push_back(
      {mid, glm::dvec3(size.x * 0.3, size.y * 0.2, size.z), glm::radians(25.0)});
  cases[1].name = "first returns outside a polygon with a hole";
  cases[1].filter.returns = pc::kReturnFirst;
  auto ring = [&](double r) {
    std::vector<glm::dvec2> v;
    for (int i = 0; i < 5; ++i) {
      const double t = glm::radians(72.0 * i + 10.0);
      v.push_back(glm::dvec2(mid) + glm::dvec2(std::cos(t) * size.x, std::sin(t) * size.y) * r);
    }
    return v;
  };
  cases[1].clip.polygons.push_back({{ring(0.35), ring(0.12)}, lo.z - 1, hi.z + 1});
  cases[1].clip.mode = pc::ClipMode::Outside;

  for (const Case& c : cases) {
    pc::PointCloud kept = cloud;
    size_t hidden = 0;
    for (size_t k = 0; k < cloud.chunks.size(); ++k) {
      const pc::PointChunk& from = cloud.chunks[k];
      pc::PointChunk& to = kept.chunks[k];
      to.vertices.clear();
      to.extras.clear();
      for (size_t i = 0; i < from.vertices.size(); ++i) {
        if (!pc::chunk_point_shown(from, i, c.filter, c.clip)) {
          ++hidden;
          continue;
        }
        to.vertices.push_back(from.vertices[i]);
        if (!from.extras.empty()) to.extras.push_back(from.extras[i]);
      }
    }
    ASSERT_GT(hidden, cloud.point_count / 10) << c.name;  // the case hides a good part
    const pc::BatchedCloud all = pc::build_batches(cloud), shown = pc::build_batches(kept);
    for (bool hqs : {false, true}) {
      if (hqs && GetParam() == "dawn") continue;
      pc::ComputeRasterOptions options;
      options.hqs = hqs;
      options.shading = pc::PointShading{pc::ColorMode::Classification};
      const auto reference = render_compute(*ctx, shown, camera, options, w, h);
      ASSERT_GT(test::coverage_stats(reference.image, kBlack, 0).coverage, 0.01) << c.name;
      options.filter = c.filter;
      options.clip = c.clip;
      std::vector<std::pair<std::string, pc::RasterKernel>> kernels = {{"default", {}}};
      if (&c == &cases[0]) {
        const auto variants = kernel_variants();
        kernels.insert(kernels.end(), variants.begin(), variants.end());
      }
      for (const auto& [name, kernel] : kernels) {
        const auto r = render_compute(*ctx, all, camera, options, w, h, false, 0,
                                      pc::DisplayPass::Auto, kernel);
        const double differ = test::differing_fraction(reference.image, r.image, 0);
        std::printf("%s, %s%s: %.4f%% of the pixels differ\n", c.name.c_str(), name.c_str(),
                    hqs ? " (HQS)" : "", 100 * differ);
        EXPECT_LE(differ, 0.005) << c.name << ", " << name << (hqs ? " HQS" : "");
      }
    }
  }

  // Highlight: every point stays; the pixels whose nearest point is in the box are tinted:
  // about those the box alone covers (fewer: some of them show a nearer point outside it).
  const pc::BatchedCloud all = pc::build_batches(cloud);
  for (bool hqs : {false, true}) {
    if (hqs && GetParam() == "dawn") continue;
    pc::ComputeRasterOptions options;
    options.hqs = hqs;
    options.shading = pc::PointShading{pc::ColorMode::Classification};
    const auto plain = render_compute(*ctx, all, camera, options, w, h);
    options.clip = cases[0].clip;
    const auto inside = render_compute(*ctx, all, camera, options, w, h);
    options.clip.mode = pc::ClipMode::Highlight;
    const auto lit = render_compute(*ctx, all, camera, options, w, h);
    EXPECT_EQ(test::coverage_stats(lit.image, kBlack, 0).covered,
              test::coverage_stats(plain.image, kBlack, 0).covered);
    const double tinted = test::differing_fraction(plain.image, lit.image, 8);
    const double in_box = test::coverage_stats(inside.image, kBlack, 0).coverage;
    std::printf("highlight%s: %.4f of the pixels tinted, %.4f in the box\n", hqs ? " (HQS)" : "",
                tinted, in_box);
    EXPECT_GT(tinted, 0.8 * in_box) << (hqs ? "HQS" : "");
    EXPECT_LT(tinted, 1.0 * in_box + 0.002) << (hqs ? "HQS" : "");
    if (!hqs && lit.visibility64) continue;  // the resolve tints: no kernel variants there
    for (const auto& [name, kernel] : kernel_variants()) {
      const auto r =
          render_compute(*ctx, all, camera, options, w, h, false, 0, pc::DisplayPass::Auto, kernel);
      EXPECT_LE(test::differing_fraction(lit.image, r.image, 0), 0.001)
          << "highlight, " << name << (hqs ? " HQS" : "");
    }
  }
}

INSTANTIATE_TEST_SUITE_P(Backends, ComputeRaster, ::testing::Values("dawn", "wgpu"),
                         [](const auto& info) { return info.param; });
