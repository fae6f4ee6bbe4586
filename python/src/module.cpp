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
  add_tile(m);
  add_render(m);
}
