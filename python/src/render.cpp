// stipple.render: scene::render_image (the pipeline of `stipple render`) with the GIL released,
// over files or points given as numpy columns; the image comes back as an (H, W, 4) uint8 array.
#include <cstddef>
#include <cstdint>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include <nanobind/nanobind.h>
#include <nanobind/ndarray.h>
#include <nanobind/stl/optional.h>
#include <nanobind/stl/string.h>
#include <nanobind/stl/vector.h>

#include "stipple/core/error.hpp"
#include "stipple/pointcloud/point_cloud.hpp"
#include "stipple/pointcloud/point_renderer.hpp"
#include "stipple/scene/render.hpp"

namespace nb = nanobind;
using namespace nb::literals;

namespace stipple::python {
namespace {

template <typename T>
using Array = nb::ndarray<const T, nb::ndim<1>, nb::device::cpu>;

// columns[name] as a strided column of T over `count` values (absent: an empty column).
template <typename T>
scene::Column<T> column(const nb::dict& columns, const char* name, size_t& count) {
  if (!columns.contains(name)) return {};
  Array<T> a;
  if (!nb::try_cast(columns[name], a, false))
    fail("points: column '{}' must be a 1-D array of {}", name,
         sizeof(T) == 8   ? "float64"
         : sizeof(T) == 2 ? "uint16"
                          : "uint8");
  if (count == SIZE_MAX) count = a.shape(0);
  if (a.shape(0) != count)
    fail("points: column '{}' has {} values, x has {}", name, a.shape(0), count);
  scene::Column<T> c;
  c.data = reinterpret_cast<const std::byte*>(a.data());
  c.stride = ptrdiff_t(a.stride(0)) * ptrdiff_t(sizeof(T));
  return c;
}

std::vector<double> numbers(const std::optional<std::vector<double>>& v, size_t n,
                            const char* what) {
  if (!v) return {};
  if (v->size() != n) fail("{}: expected {} numbers, got {}", what, n, v->size());
  return *v;
}

nb::ndarray<nb::numpy, uint8_t, nb::ndim<3>> render(
    const std::vector<std::string>& inputs, std::optional<nb::dict> columns, uint32_t width,
    uint32_t height, const std::string& camera, double azimuth, double elevation, double fov,
    const std::string& color, const std::string& renderer, float point_size,
    const std::string& point_size_mode, std::optional<std::vector<double>> background,
    std::optional<std::vector<double>> constant_color,
    std::optional<std::vector<double>> elevation_range,
    std::optional<std::vector<double>> intensity_range, bool edl, const std::string& splat,
    bool hqs, float clod_k, double max_sse, uint64_t memory_mb, uint64_t budget,
    const std::string& backend, uint32_t frames) {
  if (width == 0 || height == 0 || width > 16384 || height > 16384)
    fail("width and height must be 1 to 16384 pixels, not {}x{}", width, height);
  if (frames == 0) fail("frames must be at least 1");
  scene::RenderOptions o;
  o.width = width;
  o.height = height;
  o.camera = camera;
  o.azimuth = azimuth;
  o.elevation = elevation;
  o.fov = fov;
  o.backend = backend;
  o.frames = frames;
  o.quiet = true;
  o.scene.inputs = inputs;
  pc::PointRenderSettings& s = o.scene.render;
  s.color = pc::parse_color_mode(color);
  s.size_mode = pc::parse_point_size_mode(point_size_mode);
  s.splat = pc::parse_splat_mode(splat);
  if (point_size < 0 || point_size > 64) fail("point_size must be 0 (from the data) to 64");
  s.point_size = point_size;
  s.edl = edl;
  s.clod_k = clod_k;
  if (auto v = numbers(background, 3, "background"); !v.empty())
    s.background = glm::vec3(float(v[0]), float(v[1]), float(v[2]));
  if (auto v = numbers(constant_color, 3, "constant_color"); !v.empty())
    s.constant_color = glm::vec3(float(v[0]), float(v[1]), float(v[2]));
  if (auto v = numbers(elevation_range, 2, "elevation_range"); !v.empty()) {
    if (!(v[1] > v[0])) fail("elevation_range: max must exceed min");
    s.elevation_range = {v[0], v[1]};
  }
  if (auto v = numbers(intensity_range, 2, "intensity_range"); !v.empty()) {
    if (!(v[1] > v[0])) fail("intensity_range: max must exceed min");
    s.intensity_range = {v[0], v[1]};
  }
  if (renderer == "auto")
    o.scene.renderer = scene::Renderer::Auto;
  else if (renderer == "billboard")
    o.scene.renderer = scene::Renderer::Billboard;
  else if (renderer == "compute")
    o.scene.renderer = scene::Renderer::Compute;
  else
    fail("unknown renderer '{}' (auto, billboard, compute)", renderer);
  o.scene.hqs = hqs;
  o.scene.max_sse = max_sse;
  o.scene.memory_mb = memory_mb;
  o.scene.budget = budget;

  scene::PointColumns points;
  if (columns) {
    if (!inputs.empty()) fail("give points or input files, not both");
    size_t count = SIZE_MAX;
    points.x = column<double>(*columns, "x", count);
    points.y = column<double>(*columns, "y", count);
    points.z = column<double>(*columns, "z", count);
    if (!points.x || !points.y || !points.z) fail("points need x, y and z");
    points.intensity = column<uint16_t>(*columns, "intensity", count);
    points.red = column<uint16_t>(*columns, "red", count);
    points.green = column<uint16_t>(*columns, "green", count);
    points.blue = column<uint16_t>(*columns, "blue", count);
    points.classification = column<uint8_t>(*columns, "classification", count);
    points.return_number = column<uint8_t>(*columns, "return_number", count);
    points.number_of_returns = column<uint8_t>(*columns, "number_of_returns", count);
    points.count = count;
    if (count == 0) fail("nothing to render: the points given hold none");
  } else if (inputs.empty()) {
    fail("nothing to render: give points or input files");
  }

  scene::RenderResult r;
  // The column arrays are read without the GIL: hold a reference to each here, so that another
  // thread changing the caller's dict meanwhile cannot free them.
  std::vector<nb::object> keep_alive;
  if (columns)
    for (auto item : *columns) keep_alive.push_back(nb::borrow(item.second));
  {
    nb::gil_scoped_release release;
    if (columns) o.scene.points = scene::points_from_columns(points);
    r = scene::render_image(o);
  }
  auto* owned = new std::vector<uint8_t>(std::move(r.image.rgba));
  nb::capsule owner(owned, [](void* p) noexcept { delete static_cast<std::vector<uint8_t>*>(p); });
  return nb::ndarray<nb::numpy, uint8_t, nb::ndim<3>>(
      owned->data(), {size_t(r.image.height), size_t(r.image.width), size_t(4)}, owner);
}

}  // namespace

void add_render(nb::module_& m) {
  m.def("render", &render, "inputs"_a, "columns"_a.none(), "width"_a, "height"_a, "camera"_a,
        "azimuth"_a, "elevation"_a, "fov"_a, "color"_a, "renderer"_a, "point_size"_a,
        "point_size_mode"_a, "background"_a.none(), "constant_color"_a.none(),
        "elevation_range"_a.none(), "intensity_range"_a.none(), "edl"_a, "splat"_a, "hqs"_a,
        "clod_k"_a, "max_sse"_a, "memory_mb"_a, "budget"_a, "backend"_a, "frames"_a);
}

}  // namespace stipple::python
