#include "stipple/tiler/geo_frame.hpp"

#include <proj.h>
#include <proj_experimental.h>

#include <glm/geometric.hpp>

#include <algorithm>
#include <cmath>
#include <vector>

#include "stipple/core/error.hpp"
#include "stipple/math/geo.hpp"

namespace stipple::tiler {

std::string source_crs_definition(const io::LasHeader& header, const std::string& crs_override) {
  if (!crs_override.empty()) return crs_override;
  // The source that decides the file's CRS (io::Crs); a WKT that PROJ cannot read as a whole
  // by its AUTHORITY code.
  const io::Crs& crs = header.crs;
  if (crs.source == io::Crs::Source::Wkt && (crs.wkt_readable || crs.epsg == 0)) return crs.wkt;
  if (crs.epsg > 0) return fmt::format("EPSG:{}", crs.epsg);
  if (!header.crs.geokeys.empty())
    fail(
        "{}: its GeoTIFF keys describe a CRS without an EPSG code, which stipple cannot "
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
  if (!op)
    fail("PROJ has no transformation from '{}' to ECEF (EPSG:4978)", source_crs.substr(0, 120));
  // Traditional GIS order (lon, lat / east, north) whatever the CRS's declared axis order.
  impl_->pj = proj_normalize_for_visualization(impl_->ctx, op);
  proj_destroy(op);
  if (!impl_->pj)
    fail("PROJ cannot normalise the transformation from '{}'", source_crs.substr(0, 120));
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

void source_to_local(const EcefTransform& transform, const LocalFrame& frame,
                     const glm::dvec3* source, size_t n, glm::dvec3* local, double tolerance,
                     LatticeStats* stats) {
  LatticeStats none;
  LatticeStats& st = stats ? *stats : none;
  st.points += n;
  auto exact = [&](const glm::dvec3* src, size_t count, glm::dvec3* out) {
    std::copy(src, src + count, out);
    transform.transform(out, count);
    for (size_t i = 0; i < count; ++i) out[i] = frame.to_local(out[i]);
  };
  constexpr size_t kSamples = 32;
  if (n < 8 * kSamples || !(tolerance > 0)) {
    exact(source, n, local);
    st.exact_points += n;
    return;
  }
  glm::dvec3 lo(1e300), hi(-1e300);
  for (size_t i = 0; i < n; ++i) lo = glm::min(lo, source[i]), hi = glm::max(hi, source[i]);
  // Cell edge for a bound of tolerance / 8: s^2 / (4R) = tolerance / 8.
  const double edge_m = std::clamp(std::sqrt(geo::kWgs84A * tolerance / 2.0), 0.5, 1000.0);
  const double edge = edge_m / transform.metres_per_unit();
  const double wx = (hi.x - lo.x) / edge, wy = (hi.y - lo.y) / edge;
  if (!(wx + wy < 1e9) || (wx + 2) * (wy + 2) * 2 > double(n)) {
    exact(source, n, local);
    st.exact_points += n;
    return;
  }
  const uint32_t nx = uint32_t(wx) + 2, ny = uint32_t(wy) + 2;
  const double z0 = lo.z, z1 = hi.z > lo.z ? hi.z : lo.z + 1.0, inv_dz = 1.0 / (z1 - z0);
  const double inv_edge = 1.0 / edge;
  auto cell = [&](const glm::dvec3& p, double& fx, double& fy) {
    double gx = (p.x - lo.x) * inv_edge, gy = (p.y - lo.y) * inv_edge;
    uint32_t i = std::min(uint32_t(gx), nx - 2), j = std::min(uint32_t(gy), ny - 2);
    fx = gx - i, fy = gy - j;
    return j * nx + i;
  };
  // Pass 1: which lattice nodes the points need (thread-local scratch: no per-batch faults).
  thread_local std::vector<uint32_t> node_of;
  thread_local std::vector<glm::dvec3> nodes;
  node_of.assign(size_t(nx) * ny, UINT32_MAX);
  nodes.clear();
  // Points come in scan order, so most fall in the previous point's cell: its nodes are known.
  uint32_t previous = UINT32_MAX;
  for (size_t i = 0; i < n; ++i) {
    double fx, fy;
    uint32_t c = cell(source[i], fx, fy);
    if (c == previous) continue;
    previous = c;
    for (uint32_t k : {c, c + 1, c + nx, c + nx + 1}) {
      if (node_of[k] != UINT32_MAX) continue;
      node_of[k] = uint32_t(nodes.size() / 2);
      glm::dvec3 at(lo.x + (k % nx) * edge, lo.y + (k / nx) * edge, z0);
      nodes.push_back(at);
      nodes.push_back({at.x, at.y, z1});
    }
  }
  transform.transform(nodes.data(), nodes.size());
  for (glm::dvec3& p : nodes) p = frame.to_local(p);
  st.nodes += nodes.size();
  // Pass 2: bilinear in x, y at both heights, linear in z.
  for (size_t i = 0; i < n; ++i) {
    double fx, fy;
    uint32_t c = cell(source[i], fx, fy);
    const glm::dvec3* a = &nodes[2 * size_t(node_of[c])];
    const glm::dvec3* b = &nodes[2 * size_t(node_of[c + 1])];
    const glm::dvec3* d = &nodes[2 * size_t(node_of[c + nx])];
    const glm::dvec3* e = &nodes[2 * size_t(node_of[c + nx + 1])];
    const double w00 = (1 - fx) * (1 - fy), w10 = fx * (1 - fy), w01 = (1 - fx) * fy, w11 = fx * fy;
    glm::dvec3 bottom = a[0] * w00 + b[0] * w10 + d[0] * w01 + e[0] * w11;
    glm::dvec3 top = a[1] * w00 + b[1] * w10 + d[1] * w01 + e[1] * w11;
    local[i] = bottom + (top - bottom) * ((source[i].z - z0) * inv_dz);
  }
  // Check a spread sample against PROJ point by point.
  glm::dvec3 sample_src[kSamples], sample[kSamples];
  for (size_t k = 0; k < kSamples; ++k) sample_src[k] = source[(2 * k + 1) * n / (2 * kSamples)];
  exact(sample_src, kSamples, sample);
  double worst = 0;
  for (size_t k = 0; k < kSamples; ++k)
    worst = std::max(worst, glm::length(sample[k] - local[(2 * k + 1) * n / (2 * kSamples)]));
  if (!(worst <= tolerance)) {
    exact(source, n, local);
    st.exact_points += n;
    return;
  }
  st.max_sample_error = std::max(st.max_sample_error, worst);
}

}  // namespace stipple::tiler
