// stipple._stipple: the nanobind extension under the `stipple` Python package. It wraps
// libstipple (never the command line); every call that reads, renders or tiles runs with the GIL
// released. stipple::Error becomes stipple.Error (a RuntimeError) with the library's message.
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <nanobind/nanobind.h>
#include <nanobind/ndarray.h>
#include <nanobind/stl/optional.h>
#include <nanobind/stl/string.h>
#include <nanobind/stl/vector.h>

#include "read.hpp"
#include "stipple/core/error.hpp"
#include "stipple/io/las.hpp"
#include "stipple/io/splat_readers.hpp"

namespace nb = nanobind;
using namespace nb::literals;

namespace stipple::python {
namespace {

// Moves a byte vector into a numpy uint8 array that owns it (no copy).
nb::ndarray<nb::numpy, uint8_t, nb::ndim<1>> to_numpy(std::vector<uint8_t>&& bytes) {
  auto* owned = new std::vector<uint8_t>(std::move(bytes));
  nb::capsule owner(owned, [](void* p) noexcept { delete static_cast<std::vector<uint8_t>*>(p); });
  return nb::ndarray<nb::numpy, uint8_t, nb::ndim<1>>(owned->data(), {owned->size()}, owner);
}

// (names, formats, offsets, itemsize, bytes): stipple/__init__.py views the bytes as records.
nb::tuple read_las(const std::string& path, std::optional<std::vector<std::string>> fields) {
  ReadResult r;
  {
    nb::gil_scoped_release release;
    r = read_points(path, fields);
  }
  nb::list names, formats, offsets;
  for (const auto& f : r.fields) {
    names.append(f.name);
    formats.append(f.format);
    offsets.append(f.offset);
  }
  const size_t itemsize = r.itemsize;
  return nb::make_tuple(names, formats, offsets, itemsize, to_numpy(std::move(r.data)));
}

// Moves a vector of float vectors (glm::vec3/vec4: tightly packed floats) into a float32
// array of shape (n, k) or (n, m, k) that owns it (no copy).
template <typename V>
nb::ndarray<nb::numpy, float> float_array(std::vector<V>&& v, std::vector<size_t> shape) {
  static_assert(sizeof(V) % sizeof(float) == 0);
  auto* owned = new std::vector<V>(std::move(v));
  nb::capsule owner(owned, [](void* p) noexcept { delete static_cast<std::vector<V>*>(p); });
  return nb::ndarray<nb::numpy, float>(reinterpret_cast<float*>(owned->data()), shape.size(),
                                       shape.data(), owner);
}

// A splat file as a dict of arrays (SplatSet's fields, splats.hpp says their conventions).
nb::dict read_splats(const std::string& path) {
  io::SplatSet s;
  {
    nb::gil_scoped_release release;
    s = io::read_splats(path);
  }
  const size_t n = s.size(), rest = s.rest_count();
  nb::dict d;
  d["format"] = s.format;
  d["sh_degree"] = s.sh_degree;
  nb::list transform;  // row-major rows of the 4x4 matrix
  for (int r = 0; r < 4; ++r) {
    nb::list row;
    for (int c = 0; c < 4; ++c) row.append(s.transform[c][r]);
    transform.append(row);
  }
  d["transform"] = transform;
  d["positions"] = float_array(std::move(s.positions), {n, 3});
  d["scales"] = float_array(std::move(s.scales), {n, 3});
  d["rotations"] = float_array(std::move(s.rotations), {n, 4});
  d["opacities"] = float_array(std::move(s.opacities), {n});
  d["sh_dc"] = float_array(std::move(s.sh_dc), {n, 3});
  d["sh_rest"] = float_array(std::move(s.sh_rest), {n, rest, 3});
  return d;
}

bool is_splat_path(const std::string& path) {
  nb::gil_scoped_release release;
  return io::is_splat_path(path);
}

std::string header_json(const std::string& path) {
  nb::gil_scoped_release release;
  return io::las_header_json(io::read_las_header(path));
}

}  // namespace

void add_tile(nb::module_& m);
void add_render(nb::module_& m);

}  // namespace stipple::python

NB_MODULE(_stipple, m) {
  using namespace stipple::python;
  m.doc() = "libstipple bindings (use the stipple package)";
  nb::exception<stipple::Error>(m, "Error", PyExc_RuntimeError);
  m.def("read", &read_las, "path"_a, "fields"_a = nb::none());
  m.def("header_json", &header_json, "path"_a);
  m.def("read_splats", &read_splats, "path"_a);
  m.def("is_splat_path", &is_splat_path, "path"_a);
  add_tile(m);
  add_render(m);
}
