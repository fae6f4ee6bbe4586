#include "tiler/geo_frame.hpp"

#include <proj.h>
#include <proj_experimental.h>

#include <cmath>

#include "core/error.hpp"
#include "math/geo.hpp"

namespace stipple::tiler {

std::string source_crs_definition(const io::LasHeader& header, const std::string& crs_override) {
  if (!crs_override.empty()) return crs_override;
  if (!header.crs.wkt.empty()) return header.crs.wkt;
  if (header.crs.epsg > 0) return fmt::format("EPSG:{}", header.crs.epsg);
  if (!header.crs.geokeys.empty())
    fail("{}: its GeoTIFF keys describe a CRS without an EPSG code, which stipple cannot "
         "interpret; pass --crs EPSG:n",
         header.path);
  fail("{}: no CRS (neither a WKT nor GeoTIFF keys); pass --crs EPSG:n to say which it is",
       header.path);
}

struct EcefTransform::Impl {
  PJ_CONTEXT* ctx = nullptr;
  PJ* pj = nullptr;
  ~Impl() {
    if (pj) proj_destroy(pj);
    if (ctx) proj_context_destroy(ctx);
  }
};

EcefTransform::EcefTransform(const std::string& source_crs) : impl_(std::make_unique<Impl>()) {
  impl_->ctx = proj_context_create();
  proj_log_level(impl_->ctx, PJ_LOG_NONE);
  PJ* src = proj_create(impl_->ctx, source_crs.c_str());
  if (!src) fail("PROJ cannot read the source CRS '{}'", source_crs.substr(0, 120));
  PJ_TYPE type = proj_get_type(src);
  if (type == PJ_TYPE_BOUND_CRS) {
    PJ* base = proj_get_source_crs(impl_->ctx, src);
    if (base) type = proj_get_type(base), proj_destroy(base);
  }
  geographic_ = type == PJ_TYPE_GEOGRAPHIC_2D_CRS || type == PJ_TYPE_GEOGRAPHIC_3D_CRS;
  // A 2D CRS leaves Z undefined; LAS convention is heights in the horizontal unit. Promoting to
  // 3D gives an ellipsoidal height axis in that unit (PROJ), so feet stay feet.
  if (type == PJ_TYPE_PROJECTED_CRS || type == PJ_TYPE_GEOGRAPHIC_2D_CRS) {
    if (PJ* s3 = proj_crs_promote_to_3D(impl_->ctx, nullptr, src)) {
      proj_destroy(src);
      src = s3;
    }
  }
  if (PJ* cs = proj_crs_get_coordinate_system(impl_->ctx, src)) {
    double factor = 1;
    if (proj_cs_get_axis_info(impl_->ctx, cs, 0, nullptr, nullptr, nullptr, &factor, nullptr,
                              nullptr, nullptr))
      metres_per_unit_ = geographic_ ? factor * geo::kWgs84A : factor;  // radians -> metres
    proj_destroy(cs);
  }
  PJ* dst = proj_create(impl_->ctx, "EPSG:4978");
  PJ* op = dst ? proj_create_crs_to_crs_from_pj(impl_->ctx, src, dst, nullptr, nullptr) : nullptr;
  proj_destroy(src);
  if (dst) proj_destroy(dst);
  if (!op) fail("PROJ has no transformation from '{}' to ECEF (EPSG:4978)", source_crs.substr(0, 120));
  // Traditional GIS order (lon, lat / east, north) whatever the CRS's declared axis order.
  impl_->pj = proj_normalize_for_visualization(impl_->ctx, op);
  proj_destroy(op);
  if (!impl_->pj) fail("PROJ cannot normalise the transformation from '{}'", source_crs.substr(0, 120));
}

EcefTransform::~EcefTransform() = default;

void EcefTransform::transform(glm::dvec3* p, size_t n) const {
  if (n == 0) return;
  const size_t stride = sizeof(glm::dvec3);
  proj_trans_generic(impl_->pj, PJ_FWD, &p->x, stride, n, &p->y, stride, n, &p->z, stride, n,
                     nullptr, 0, 0);
  for (size_t i = 0; i < n; ++i)
    if (!std::isfinite(p[i].x) || !std::isfinite(p[i].y) || !std::isfinite(p[i].z))
      fail("PROJ could not transform a point to ECEF (outside the CRS's area of use?)");
}

glm::dvec3 LocalFrame::to_local(const glm::dvec3& ecef) const {
  return glm::transpose(enu_to_ecef) * (ecef - origin_ecef);
}

glm::dvec3 LocalFrame::to_ecef(const glm::dvec3& local) const {
  return origin_ecef + enu_to_ecef * local;
}

LocalFrame make_local_frame(const glm::dvec3& ecef_centre) {
  glm::dvec3 llh = geo::ecef_to_geodetic(ecef_centre);
  LocalFrame f;
  f.origin_ecef = ecef_centre;
  f.enu_to_ecef = geo::enu_basis(llh.x, llh.y);
  return f;
}

}  // namespace stipple::tiler
