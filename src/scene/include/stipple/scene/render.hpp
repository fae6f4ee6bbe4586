#pragma once
// Headless rendering to an image in memory: the pipeline of `stipple render` (which writes the
// image as PNG) and of stipple.render in Python (which returns it as a numpy array), one
// function for both so that they draw the same pixels for the same points and options.
#include <cstddef>
#include <cstdint>
#include <functional>
#include <memory>
#include <span>
#include <string>

#include "stipple/engine/render_plugins.hpp"
#include "stipple/pointcloud/point_cloud.hpp"
#include "stipple/pointcloud/pointlets.hpp"
#include "stipple/renderer/gpu.hpp"
#include "stipple/scene/scene.hpp"

namespace stipple::scene {

struct RenderOptions {
  SceneOptions scene;  // inputs (or points in memory), point settings, renderer, streaming
  uint32_t width = 1280, height = 720;
  // 'eye_x,eye_y,eye_z,target_x,target_y,target_z' in the data's coordinates (Z up); empty:
  // framed from azimuth and elevation (degrees) so that the data fills the image.
  std::string camera;
  double azimuth = 30.0, elevation = 40.0, fov = 50.0;
  std::string backend;  // "dawn", "wgpu"; empty: $STIPPLE_BACKEND, else wgpu
  uint32_t frames = 1;  // frames drawn once the scene is loaded; the last is kept
  std::string dump_graph;
  bool pipelined = false;
  uint64_t max_frames = 10000;  // streamed sources: keep the image after this many frames
  bool quiet = false;           // no "renderer: ..." line on stdout
};

struct RenderResult {
  gpu::Image image;      // RGBA8, top row first, width x height
  bool compute = false;  // the compute rasterizer drew it (else billboards)
  std::string renderer_reason;
  std::string color_source;  // the colour mode shown ("rgb", "elevation"...)
  float point_size = 0;      // pixels
  uint64_t splats = 0;       // Gaussian splats drawn beside the points (splat files among inputs)
  gpu::AdapterDescription adapter;
  RenderStats stats;  // every frame's pass times
  uint64_t transient_textures_created = 0, transient_buffers_created = 0;
  double load_seconds = 0, seconds = 0;
  bool cache_built = false;            // the virtualized path built its pointlet cache
  pc::PointletBuildStats cache_build;  // and how (its phases), when it did
};

// Renders the scene of `options` headless and returns the last frame. Throws stipple::Error
// (naming the input) for what cannot be read or drawn.
RenderResult render_image(const RenderOptions& options);

// render --progressive: a first image at once, then the full one. The first is drawn in memory
// from about `sample_points` points read across the whole input (pc::read_las_sample: LAS
// records at a stride, LAZ the first points of every chunk) and handed to `first` as soon as it
// is drawn, while the pointlet cache the virtualized path needs builds on another thread (from
// when the sample has been read); the
// full render follows once the cache is ready (the same image as render_image alone). Inputs
// other than LAS/LAZ files (COPC, tilesets) stream as they do without it, and `first` is not
// called. Returns the full render.
RenderResult render_progressive(const RenderOptions& options, uint64_t sample_points,
                                const std::function<void(const RenderResult&)>& first);

// A column of a caller's point array: `count` values of T, `stride` bytes apart (null: absent).
template <typename T>
struct Column {
  const std::byte* data = nullptr;
  ptrdiff_t stride = sizeof(T);
  T operator[](size_t i) const;
  explicit operator bool() const { return data != nullptr; }
};

// Points held by the caller (numpy arrays in Python): source coordinates (Z up) and optional
// attributes named as in LAS.
struct PointColumns {
  size_t count = 0;
  Column<double> x, y, z;
  Column<uint16_t> intensity, red, green, blue;
  Column<uint8_t> classification, return_number, number_of_returns;
};

// The points as a cloud to draw, made exactly as a LAS file with the same values is loaded
// (chunks of `chunk_points`; RGB taken as 8-bit when every R, G, B of the first 65536 points is
// at most 255, as the LAS reader does). Throws stipple::Error for a non-finite coordinate.
std::shared_ptr<const pc::PointCloud> points_from_columns(const PointColumns& points,
                                                          size_t chunk_points = 1 << 20);

}  // namespace stipple::scene
