// The web build's CRS reader: PROJ is not built for WebAssembly (yet), so a LAS file's CRS is
// not read there; drawing needs none (points are drawn in the file's own coordinates), and no
// point is turned to lon/lat.
#include "las_detail.hpp"
#include "stipple/core/log.hpp"

namespace stipple::io::detail {

Crs parse_crs(const std::vector<Vlr>& vlrs, const std::vector<Vlr>& evlrs, uint16_t, bool) {
  if (!vlrs.empty() || !evlrs.empty()) STIPPLE_DEBUG("the web build does not read CRS records");
  return Crs{};
}

}  // namespace stipple::io::detail

namespace stipple::io {

// No PROJ: no lon/lat for an inspected point in the page (valid() is false; its source
// coordinates are shown in full).
LonLatTransform::LonLatTransform(const Crs&) {}
LonLatTransform::~LonLatTransform() = default;
std::optional<glm::dvec3> LonLatTransform::operator()(const glm::dvec3&) const {
  return std::nullopt;
}

}  // namespace stipple::io
