#pragma once
// Source CRS -> ECEF (EPSG:4978) with PROJ in double precision, then into one local
// east-north-up frame (metres) for the whole tileset. The octree is built in that frame, so tile
// boxes are axis-aligned there; the tileset's root transform (ENU -> ECEF) makes them oriented
// boxes in ECEF.
#include <cstdint>
#include <memory>
#include <string>

#include <glm/mat3x3.hpp>
#include <glm/vec3.hpp>

#include "stipple/io/las.hpp"

namespace stipple::tiler {

// The source CRS definition PROJ gets for an input: --crs override, else the WKT, else the
// GeoTIFF EPSG code. Throws stipple::Error when there is none.
std::string source_crs_definition(const io::LasHeader& header, const std::string& crs_override);

// One PROJ transformation source -> ECEF. Not thread-safe: one per thread (own PJ_CONTEXT).
class EcefTransform {
 public:
  explicit EcefTransform(const std::string& source_crs);
  ~EcefTransform();
  EcefTransform(const EcefTransform&) = delete;
  EcefTransform& operator=(const EcefTransform&) = delete;
  // In place, source coordinates -> ECEF metres. Throws on points PROJ cannot transform.
  void transform(glm::dvec3* points, size_t count) const;
  // Metres per unit of the source's horizontal axes (degrees: ~metres per degree at the equator).
  double metres_per_unit() const { return metres_per_unit_; }
  bool geographic() const { return geographic_; }

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
  double metres_per_unit_ = 1.0;
  bool geographic_ = false;
};

struct LocalFrame {
  glm::dvec3 origin_ecef{0};
  glm::dmat3 enu_to_ecef{1.0};  // columns: east, north, up
  glm::dvec3 to_local(const glm::dvec3& ecef) const;
  glm::dvec3 to_ecef(const glm::dvec3& local) const;
};

// Frame anchored at the ellipsoid point under (or above) `ecef_centre`.
LocalFrame make_local_frame(const glm::dvec3& ecef_centre);

// Source -> local ENU for a batch of points, with PROJ evaluated on a lattice rather than per
// point. The map is smooth: horizontally its second derivative is about the Earth's curvature
// (1/R), so bilinear interpolation over cells of edge s errs by at most ~s^2/(4R); vertically it
// is affine (a height moves a point along the ellipsoid normal, geoid or datum shifts
// included). Cells are sized for an error of `tolerance` / 8 and a sample of every batch is
// checked against PROJ point by point: a batch whose sample errs by more than `tolerance` (an
// odd CRS), or whose extent would need more lattice nodes than it has points, is transformed
// exactly instead. So results stay within `tolerance` of PROJ's, at a fraction of its cost.
struct LatticeStats {
  uint64_t points = 0, exact_points = 0, nodes = 0;
  double max_sample_error = 0;  // metres, over the checked samples of interpolated batches
};
void source_to_local(const EcefTransform& transform, const LocalFrame& frame,
                     const glm::dvec3* source, size_t count, glm::dvec3* local, double tolerance,
                     LatticeStats* stats = nullptr);

}  // namespace stipple::tiler
