// Coordinate reference system of a LAS file: the OGC WKT VLR and/or GeoTIFF keys, with names and
// units looked up through PROJ. PROJ is best effort: any failure leaves fields empty.
#include <proj.h>

#include <algorithm>
#include <cmath>
#include <cstring>

#include <fmt/format.h>

#include "las_detail.hpp"

namespace stipple::io {

std::string Crs::describe() const {
  if (empty()) return "no CRS";
  std::string s = epsg ? fmt::format("EPSG:{}", epsg) : std::string("custom CRS");
  if (!name.empty()) s += fmt::format(" ({})", name);
  if (vertical_epsg) s += fmt::format(" + vertical EPSG:{}", vertical_epsg);
  if (geographic) {
    s += ", geographic degrees";
  } else if (!linear_unit.empty()) {
    s += fmt::format(", unit {}", linear_unit);
  }
  return s;
}

namespace detail {
namespace {

const Vlr* find(const std::vector<Vlr>& list, const char* user, uint16_t id) {
  for (const Vlr& v : list) {
    if (v.user_id == user && v.record_id == id) return &v;
  }
  return nullptr;
}

std::string unit_name(uint16_t code) {
  switch (code) {
    case 9001:
      return "metre";
    case 9002:
      return "foot";
    case 9003:
      return "US survey foot";
    default:
      return {};
  }
}

// RAII for the PROJ objects used below.
struct Proj {
  PJ_CONTEXT* ctx = proj_context_create();
  std::vector<PJ*> objects;
  Proj() {
    // PROJ's own messages (e.g. a missing proj.db) would bypass our logger; a missing name is
    // not an error for us.
    if (ctx) {
      proj_log_level(ctx, PJ_LOG_NONE);
      proj_log_func(ctx, nullptr, [](void*, int, const char*) {});
    }
  }
  ~Proj() {
    for (PJ* o : objects) proj_destroy(o);
    if (ctx) proj_context_destroy(ctx);
  }
  PJ* keep(PJ* o) {
    if (o) objects.push_back(o);
    return o;
  }
};

int id_code(const PJ* o) {
  const char* auth = proj_get_id_auth_name(o, 0);
  const char* code = proj_get_id_code(o, 0);
  if (!auth || !code || std::strcmp(auth, "EPSG") != 0) return 0;
  return std::atoi(code);
}

bool is_geographic(PJ_TYPE t) {
  return t == PJ_TYPE_GEOGRAPHIC_2D_CRS || t == PJ_TYPE_GEOGRAPHIC_3D_CRS ||
         t == PJ_TYPE_GEOGRAPHIC_CRS;
}

void resolve_with_proj(Crs& crs) {
  Proj p;
  if (!p.ctx) return;
  PJ* obj = nullptr;
  if (!crs.wkt.empty()) obj = p.keep(proj_create(p.ctx, crs.wkt.c_str()));
  if (!obj && crs.epsg > 0) {
    obj = p.keep(proj_create(p.ctx, fmt::format("EPSG:{}", crs.epsg).c_str()));
  }
  if (!obj) return;
  PJ* horizontal = obj;
  if (proj_get_type(obj) == PJ_TYPE_COMPOUND_CRS) {
    horizontal = p.keep(proj_crs_get_sub_crs(p.ctx, obj, 0));
    PJ* vertical = p.keep(proj_crs_get_sub_crs(p.ctx, obj, 1));
    if (vertical && crs.vertical_epsg == 0) crs.vertical_epsg = id_code(vertical);
    if (!horizontal) horizontal = obj;
  }
  if (const char* name = proj_get_name(horizontal)) crs.name = name;
  if (crs.epsg == 0) crs.epsg = id_code(horizontal);
  if (is_geographic(proj_get_type(horizontal))) crs.geographic = true;
  if (crs.linear_unit.empty() && !crs.geographic) {
    PJ* cs = p.keep(proj_crs_get_coordinate_system(p.ctx, horizontal));
    const char* unit = nullptr;
    if (cs &&
        proj_cs_get_axis_info(p.ctx, cs, 0, nullptr, nullptr, nullptr, nullptr, &unit, nullptr,
                              nullptr) &&
        unit) {
      crs.linear_unit = unit;
    }
  }
}

}  // namespace

Crs parse_crs(const std::vector<Vlr>& vlrs, const std::vector<Vlr>& evlrs, bool resolve_names) {
  Crs crs;
  const Vlr* wkt = find(vlrs, "LASF_Projection", 2112);
  if (!wkt) wkt = find(evlrs, "LASF_Projection", 2112);
  if (wkt) {
    crs.wkt.assign(wkt->data.begin(), wkt->data.end());
    crs.wkt.erase(std::find(crs.wkt.begin(), crs.wkt.end(), '\0'), crs.wkt.end());
  }
  if (const Vlr* keys = find(vlrs, "LASF_Projection", 34735)) {
    const size_t words = keys->data.size() / 2;
    if (words >= 4) {
      const uint16_t count = load<uint16_t>(keys->data.data() + 6);
      for (size_t k = 0; k < count && 4 + 4 * k + 4 <= words; ++k) {
        std::array<uint16_t, 4> e;
        for (int j = 0; j < 4; ++j) e[j] = load<uint16_t>(keys->data.data() + 8 + 8 * k + 2 * j);
        crs.geokeys.push_back(e);
      }
    }
  }
  if (const Vlr* d = find(vlrs, "LASF_Projection", 34736)) {
    for (size_t at = 0; at + 8 <= d->data.size(); at += 8) {
      crs.geo_doubles.push_back(load<double>(d->data.data() + at));
    }
  }
  if (const Vlr* a = find(vlrs, "LASF_Projection", 34737)) {
    crs.geo_ascii.assign(a->data.begin(), a->data.end());
    while (!crs.geo_ascii.empty() && crs.geo_ascii.back() == '\0') crs.geo_ascii.pop_back();
  }
  int projected = 0, geographic = 0;
  for (const auto& k : crs.geokeys) {
    // Only values stored inline (TIFFTagLocation 0) are codes; 32767 means user-defined.
    if (k[1] != 0 || k[3] == 32767) continue;
    switch (k[0]) {
      case 1024:
        crs.geographic = crs.geographic || k[3] == 2;
        break;
      case 2048:
        geographic = k[3];
        break;
      case 3072:
        projected = k[3];
        break;
      case 3076:
        crs.linear_unit = unit_name(k[3]);
        break;
      case 4096:
        crs.vertical_epsg = k[3];
        break;
      default:
        break;
    }
  }
  crs.epsg = projected ? projected : geographic;
  if (!crs.wkt.empty()) {
    // WKT1 GEOGCS / WKT2 GEOGCRS or GEOGRAPHICCRS at the top level means degrees.
    const size_t start = crs.wkt.find_first_not_of(" \t\r\n");
    if (start != std::string::npos) {
      const std::string head = crs.wkt.substr(start, 14);
      if (head.rfind("GEOGCS", 0) == 0 || head.rfind("GEOGCRS", 0) == 0 ||
          head.rfind("GEOGRAPHICCRS", 0) == 0) {
        crs.geographic = true;
      }
    }
  }
  if (crs.geographic) crs.linear_unit = "degree";
  if (resolve_names && (!crs.wkt.empty() || crs.epsg > 0)) resolve_with_proj(crs);
  if (crs.epsg == 0 && !crs.wkt.empty()) {
    // Fallback when PROJ cannot help: WKT1 ending in its own AUTHORITY["EPSG","n"]].
    const size_t at = crs.wkt.rfind("AUTHORITY[\"EPSG\",\"");
    if (at != std::string::npos) {
      const size_t close = crs.wkt.find("\"]", at + 18);
      if (close != std::string::npos &&
          crs.wkt.find_first_not_of(" \t\r\n]", close + 2) == std::string::npos &&
          std::count(crs.wkt.begin() + close + 2, crs.wkt.end(), ']') == 1) {
        crs.epsg = std::atoi(crs.wkt.c_str() + at + 18);
      }
    }
  }
  return crs;
}

}  // namespace detail

LonLatTransform::LonLatTransform(const Crs& crs) {
  if (crs.empty()) return;
  PJ_CONTEXT* ctx = proj_context_create();
  if (!ctx) return;
  proj_log_level(ctx, PJ_LOG_NONE);
  context_ = ctx;
  PJ* source = nullptr;
  if (!crs.wkt.empty()) source = proj_create(ctx, crs.wkt.c_str());
  if (!source && crs.epsg > 0) source = proj_create(ctx, fmt::format("EPSG:{}", crs.epsg).c_str());
  if (!source) return;
  PJ* target = proj_create(ctx, "EPSG:4979");  // WGS 84 3D: lat, lon, ellipsoidal height
  if (!target) target = proj_create(ctx, "EPSG:4326");
  PJ* raw =
      target ? proj_create_crs_to_crs_from_pj(ctx, source, target, nullptr, nullptr) : nullptr;
  PJ* normalized = raw ? proj_normalize_for_visualization(ctx, raw) : nullptr;  // lon, lat
  if (raw) proj_destroy(raw);
  if (target) proj_destroy(target);
  proj_destroy(source);
  transform_ = normalized;
}

LonLatTransform::~LonLatTransform() {
  if (transform_) proj_destroy(static_cast<PJ*>(transform_));
  if (context_) proj_context_destroy(static_cast<PJ_CONTEXT*>(context_));
}

std::optional<glm::dvec3> LonLatTransform::operator()(const glm::dvec3& p) const {
  if (!transform_) return std::nullopt;
  PJ_COORD c = proj_coord(p.x, p.y, p.z, 0);
  PJ_COORD out = proj_trans(static_cast<PJ*>(transform_), PJ_FWD, c);
  if (!std::isfinite(out.xyz.x) || !std::isfinite(out.xyz.y) || out.xyz.x == HUGE_VAL)
    return std::nullopt;
  return glm::dvec3(out.xyz.x, out.xyz.y, out.xyz.z);
}

}  // namespace stipple::io
