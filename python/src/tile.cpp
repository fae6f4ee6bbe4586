// stipple.tile / stipple.merge: the tiler library (build_tileset, merge_parts) with the GIL
// released; the progress callback takes it back for each call.
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <tuple>
#include <vector>

#include <nanobind/nanobind.h>
#include <nanobind/stl/function.h>
#include <nanobind/stl/string.h>
#include <nanobind/stl/vector.h>

#include "stipple/core/error.hpp"
#include "stipple/core/memory.hpp"
#include "stipple/tiler/tiler.hpp"

namespace nb = nanobind;
using namespace nb::literals;

namespace stipple::python {
namespace {

using ProgressFn = std::function<void(const std::string&, uint64_t, uint64_t)>;

// Calls a Python callable from any thread. An exception it raises stops the work (as a
// stipple::Error) and is raised again once the library has returned.
struct PyProgress {
  nb::object callable;
  std::mutex mutex;
  std::optional<nb::python_error> error;

  ProgressFn wrap() {
    if (callable.is_none()) return {};
    return [this](const std::string& phase, uint64_t done, uint64_t total) {
      nb::gil_scoped_acquire gil;
      if (error) fail("stopped: the progress callback raised");
      try {
        callable(phase, done, total);
      } catch (nb::python_error& e) {
        error.emplace(std::move(e));
        fail("stopped: the progress callback raised");
      }
    };
  }
  // After the library returned or threw: the callback's own exception first.
  void rethrow() {
    if (error) {
      nb::python_error e = std::move(*error);
      error.reset();
      e.restore();
      throw nb::python_error();
    }
  }
};

nb::dict stats_dict(const tiler::TileStats& s) {
  nb::dict d;
  d["points"] = s.points;
  d["tiles"] = s.tiles;
  d["depth"] = s.depth;
  d["chunks"] = s.chunks;
  d["root_spacing"] = s.root_spacing;
  d["seconds"] = s.seconds;
  return d;
}

nb::dict tile(std::vector<std::string> inputs, std::string output, std::string format,
              std::string crs, double spacing, std::string max_memory, unsigned threads, bool force,
              size_t max_node_points, std::string compress, bool implicit, int subtree_levels,
              std::string subset, nb::object progress) {
  tiler::TileOptions o;
  o.inputs = std::move(inputs);
  o.output = std::move(output);
  if (format != "glb" && format != "pnts") fail("format '{}' is not glb or pnts", format);
  o.format = format == "pnts" ? tiler::Format::Pnts : tiler::Format::Glb;
  o.crs = std::move(crs);
  o.spacing = spacing;
  o.max_memory = parse_size(max_memory);
  o.threads = threads;
  o.force = force;
  o.max_node_points = max_node_points;
  o.compression = std::move(compress);
  o.implicit = implicit;
  o.subtree_levels = subtree_levels;
  if (!subset.empty()) std::tie(o.subset_index, o.subset_count) = tiler::parse_subset(subset);
  PyProgress p{std::move(progress)};
  o.progress = p.wrap();
  tiler::TileStats s;
  try {
    nb::gil_scoped_release release;
    s = tiler::build_tileset(o);
  } catch (const Error&) {
    p.rethrow();
    throw;
  }
  return stats_dict(s);
}

nb::dict merge(std::vector<std::string> parts, std::string output, bool force, unsigned threads,
               std::string max_memory, nb::object progress) {
  tiler::MergeOptions o;
  o.parts = std::move(parts);
  o.output = std::move(output);
  o.force = force;
  o.threads = threads;
  o.max_memory = parse_size(max_memory);
  PyProgress p{std::move(progress)};
  o.progress = p.wrap();
  tiler::TileStats s;
  try {
    nb::gil_scoped_release release;
    s = tiler::merge_parts(o);
  } catch (const Error&) {
    p.rethrow();
    throw;
  }
  return stats_dict(s);
}

}  // namespace

void add_tile(nb::module_& m) {
  m.def("tile", &tile, "inputs"_a, "output"_a, "format"_a, "crs"_a, "spacing"_a, "max_memory"_a,
        "threads"_a, "force"_a, "max_node_points"_a, "compress"_a, "implicit"_a, "subtree_levels"_a,
        "subset"_a, "progress"_a.none());
  m.def("merge", &merge, "parts"_a, "output"_a, "force"_a, "threads"_a, "max_memory"_a,
        "progress"_a.none());
}

}  // namespace stipple::python
