// Coordinate reference system of a LAS file: the OGC WKT VLR and/or GeoTIFF keys, with names and
// units looked up through PROJ. PROJ is best effort: any failure leaves fields empty.
#include <proj.h>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <initializer_list>
#include <optional>
#include <string_view>
#include <unordered_map>

#include <fmt/format.h>

#include "las_detail.hpp"

namespace stipple::io {

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

// One PROJ context per thread, kept for the thread's life: creating a context and opening its
// database (proj.db, sqlite) costs far more than the look-ups made through it, and a tiler or
// viewer that opens thousands of files (or a fuzzer that opens millions) would pay that per file.
// A context is not thread-safe, hence one per thread.
PJ_CONTEXT* thread_context() {
  struct Context {
    PJ_CONTEXT* ctx = proj_context_create();
    Context() {
      // PROJ's own messages (e.g. a missing proj.db) would bypass our logger; a missing name is
      // not an error for us.
      if (ctx) {
        proj_log_level(ctx, PJ_LOG_NONE);
        proj_log_func(ctx, nullptr, [](void*, int, const char*) {});
      }
    }
    ~Context() {
      if (ctx) proj_context_destroy(ctx);
    }
    Context(const Context&) = delete;
    Context& operator=(const Context&) = delete;
  };
  thread_local Context context;
  return context.ctx;
}

// The PROJ objects made for one look-up, destroyed after it (the context stays).
struct Proj {
  PJ_CONTEXT* ctx = thread_context();
  std::vector<PJ*> objects;
  Proj() = default;
  Proj(const Proj&) = delete;
  Proj& operator=(const Proj&) = delete;
  ~Proj() {
    for (PJ* o : objects) proj_destroy(o);
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

// What one source (the WKT or the GeoTIFF keys) says about the CRS.
struct CrsFacts {
  int epsg = 0, vertical_epsg = 0;
  bool geographic = false;
  std::string name, linear_unit;
  bool readable = false;  // PROJ read the definition
};

// A CRS from a definition: "AUTHORITY:CODE" (what the GeoTIFF keys give) or the text of a WKT
// VLR. proj_create takes any text, and one that is neither WKT, a PROJ string nor a code it
// looks up as an object name, a search of the whole database (0.4-0.5 s natively, seconds under
// ASan): every damaged WKT VLR would pay that. So WKT goes to PROJ's WKT parser alone; an
// authority and a numeric code, an OGC URN or a PROJ string to proj_create; anything else
// nowhere (the WKT tree reader below still reads what it can).
PJ* create_crs(PJ_CONTEXT* ctx, const std::string& definition) {
  const size_t mark = definition.find_first_of("[(:");
  if (mark != std::string::npos && definition[mark] != ':')
    return proj_create_from_wkt(ctx, definition.c_str(), nullptr, nullptr, nullptr);
  auto all = [](std::string_view s, auto pred) {
    return std::all_of(s.begin(), s.end(),
                       [&](char c) { return pred(static_cast<unsigned char>(c)); });
  };
  const std::string_view d = definition;
  const bool code = mark != std::string::npos && mark > 0 && mark <= 16 &&
                    d.size() - mark - 1 <= 10 && d.size() > mark + 1 &&
                    all(d.substr(0, mark), [](int c) { return std::isalnum(c) || c == '_'; }) &&
                    all(d.substr(mark + 1), [](int c) { return std::isdigit(c); });
  if (code || d.starts_with("urn:ogc:def:crs:") || d.starts_with("+proj="))
    return proj_create(ctx, definition.c_str());
  return nullptr;
}

// A CRS definition ("EPSG:n" or WKT) through PROJ.
CrsFacts facts_from_proj_uncached(const std::string& definition) {
  CrsFacts f;
  Proj p;
  if (!p.ctx) return f;
  PJ* obj = p.keep(create_crs(p.ctx, definition));
  if (!obj) return f;
  f.readable = true;
  PJ* horizontal = obj;
  if (proj_get_type(obj) == PJ_TYPE_COMPOUND_CRS) {
    horizontal = p.keep(proj_crs_get_sub_crs(p.ctx, obj, 0));
    if (PJ* vertical = p.keep(proj_crs_get_sub_crs(p.ctx, obj, 1)))
      f.vertical_epsg = id_code(vertical);
    if (!horizontal) horizontal = obj;
  }
  if (const char* name = proj_get_name(horizontal)) f.name = name;
  f.epsg = id_code(horizontal);
  f.geographic = is_geographic(proj_get_type(horizontal));
  if (!f.geographic) {
    PJ* cs = p.keep(proj_crs_get_coordinate_system(p.ctx, horizontal));
    const char* unit = nullptr;
    if (cs &&
        proj_cs_get_axis_info(p.ctx, cs, 0, nullptr, nullptr, nullptr, nullptr, &unit, nullptr,
                              nullptr) &&
        unit) {
      f.linear_unit = unit;
    }
  }
  return f;
}

// facts_from_proj, remembered per thread: the files of one survey share their CRS, and even with
// the context kept a look-up runs several queries on PROJ's database. Bounded: definitions over
// 16 KiB are not kept, and the table starts over at 64 entries.
CrsFacts facts_from_proj(const std::string& definition) {
  thread_local std::unordered_map<std::string, CrsFacts> seen;
  if (const auto it = seen.find(definition); it != seen.end()) return it->second;
  CrsFacts f = facts_from_proj_uncached(definition);
  if (definition.size() <= (16u << 10)) {
    if (seen.size() >= 64) seen.clear();
    seen.emplace(definition, f);
  }
  return f;
}

// WKT1 as a tree of KEYWORD[values, children], enough to read the top-level name, AUTHORITY and
// UNIT of a WKT that PROJ cannot read as a whole (a VERTCS nested inside the PROJCS, as some
// writers put it). Untrusted text: depth and node count are bounded.
struct WktNode {
  std::string keyword;
  std::vector<std::string> values;  // quoted strings (unquoted) and bare words, in order
  std::vector<WktNode> children;
};

class WktReader {
 public:
  explicit WktReader(std::string_view text) : s_(text) {}
  std::optional<WktNode> read() {
    WktNode top;
    if (!node(top, 0)) return std::nullopt;
    return top;
  }

 private:
  std::string_view s_;
  size_t at_ = 0, nodes_ = 0;

  void space() {
    while (at_ < s_.size() && std::isspace(static_cast<unsigned char>(s_[at_]))) ++at_;
  }
  bool node(WktNode& n, int depth) {
    if (depth > 32 || ++nodes_ > 10000) return false;
    space();
    const size_t start = at_;
    while (at_ < s_.size() && (std::isalnum(static_cast<unsigned char>(s_[at_])) || s_[at_] == '_'))
      ++at_;
    n.keyword.assign(s_.substr(start, at_ - start));
    for (char& c : n.keyword) c = char(std::toupper(static_cast<unsigned char>(c)));
    space();
    if (n.keyword.empty() || at_ >= s_.size() || (s_[at_] != '[' && s_[at_] != '(')) return false;
    const char close = s_[at_++] == '[' ? ']' : ')';
    for (;;) {
      space();
      if (at_ >= s_.size()) return false;
      if (s_[at_] == close) {
        ++at_;
        return true;
      }
      if (s_[at_] == '"') {
        std::string value;
        for (++at_;; ++at_) {
          if (at_ >= s_.size()) return false;
          if (s_[at_] == '"') {
            if (at_ + 1 < s_.size() && s_[at_ + 1] == '"') {  // "" is a quote inside
              value += '"';
              ++at_;
              continue;
            }
            ++at_;
            break;
          }
          value += s_[at_];
        }
        n.values.push_back(std::move(value));
      } else {
        // A number or an enumeration word, or a child node (a word followed by a bracket).
        const size_t word = at_;
        while (at_ < s_.size() && s_[at_] != ',' && s_[at_] != close && s_[at_] != '[' &&
               s_[at_] != '(' && s_[at_] != ']' && s_[at_] != ')')
          ++at_;
        if (at_ < s_.size() && (s_[at_] == '[' || s_[at_] == '(')) {
          at_ = word;
          n.children.emplace_back();
          if (!node(n.children.back(), depth + 1)) return false;
        } else {
          // No progress (a bracket that closes nothing here, as in "A[1)"): malformed, and
          // looping on it would grow the values without end.
          if (at_ == word) return false;
          std::string_view v = s_.substr(word, at_ - word);
          while (!v.empty() && std::isspace(static_cast<unsigned char>(v.back())))
            v.remove_suffix(1);
          n.values.emplace_back(v);
        }
      }
      space();
      if (at_ < s_.size() && s_[at_] == ',') ++at_;
    }
  }
};

const WktNode* wkt_child(const WktNode& n, std::initializer_list<std::string_view> keywords) {
  for (const WktNode& c : n.children)
    for (std::string_view k : keywords)
      if (c.keyword == k) return &c;
  return nullptr;
}

// AUTHORITY["EPSG","n"] (WKT1) or ID["EPSG",n] (WKT2) directly under a node.
int wkt_epsg(const WktNode* n) {
  if (!n) return 0;
  const WktNode* a = wkt_child(*n, {"AUTHORITY", "ID"});
  if (!a || a->values.size() < 2 || a->values[0] != "EPSG") return 0;
  return std::atoi(a->values[1].c_str());
}

CrsFacts facts_from_wkt_tree(const WktNode& top) {
  CrsFacts f;
  const WktNode* horizontal = &top;
  // Nested in the horizontal CRS is not valid WKT1, but some writers put it there.
  const WktNode* vertical = wkt_child(top, {"VERT_CS", "VERTCS", "VERTCRS", "VERTICALCRS"});
  if (top.keyword == "COMPD_CS" || top.keyword == "COMPOUNDCRS") {
    horizontal = wkt_child(top, {"PROJCS", "GEOGCS", "GEOCCS", "PROJCRS", "PROJECTEDCRS", "GEOGCRS",
                                 "GEOGRAPHICCRS", "GEODCRS", "GEODETICCRS"});
    if (!horizontal) return f;
  }
  if (!horizontal->values.empty()) f.name = horizontal->values[0];
  f.epsg = wkt_epsg(horizontal);
  f.vertical_epsg = wkt_epsg(vertical);
  const std::string& k = horizontal->keyword;
  f.geographic = k == "GEOGCS" || k == "GEOGCRS" || k == "GEOGRAPHICCRS";
  if (!f.geographic)
    if (const WktNode* unit = wkt_child(*horizontal, {"UNIT", "LENGTHUNIT"});
        unit && !unit->values.empty())
      f.linear_unit = unit->values[0];
  return f;
}

CrsFacts wkt_facts(const std::string& wkt, bool resolve) {
  CrsFacts f = resolve ? facts_from_proj(wkt) : CrsFacts{};
  // What PROJ left unsaid (it reads some WKT in part, or not at all), from the text itself.
  if (f.epsg && f.name.size() && (f.geographic || f.linear_unit.size())) return f;
  if (const auto tree = WktReader(wkt).read()) {
    const CrsFacts t = facts_from_wkt_tree(*tree);
    if (!f.epsg) f.epsg = t.epsg;
    if (!f.vertical_epsg) f.vertical_epsg = t.vertical_epsg;
    if (f.name.empty()) f.name = t.name;
    if (!f.readable) f.geographic = t.geographic;
    if (f.linear_unit.empty() && !f.geographic) f.linear_unit = t.linear_unit;
  }
  return f;
}

CrsFacts geotiff_facts(const std::vector<std::array<uint16_t, 4>>& geokeys, bool resolve) {
  CrsFacts f;
  int projected = 0, geographic = 0;
  for (const auto& k : geokeys) {
    // Only values stored inline (TIFFTagLocation 0) are codes; 32767 means user-defined.
    if (k[1] != 0 || k[3] == 32767) continue;
    switch (k[0]) {
      case 1024:
        f.geographic = f.geographic || k[3] == 2;
        break;
      case 2048:
        geographic = k[3];
        break;
      case 3072:
        projected = k[3];
        break;
      case 3076:
        f.linear_unit = unit_name(k[3]);
        break;
      case 4096:
        f.vertical_epsg = k[3];
        break;
      default:
        break;
    }
  }
  f.epsg = projected ? projected : geographic;
  if (resolve && f.epsg > 0) {
    const CrsFacts p = facts_from_proj(fmt::format("EPSG:{}", f.epsg));
    f.name = p.name;
    f.geographic = f.geographic || p.geographic;
    if (f.linear_unit.empty()) f.linear_unit = p.linear_unit;
  }
  return f;
}

}  // namespace

Crs parse_crs(const std::vector<Vlr>& vlrs, const std::vector<Vlr>& evlrs, uint16_t global_encoding,
              bool resolve_names) {
  Crs crs;
  const Vlr* wkt = find(vlrs, "LASF_Projection", 2112);
  if (!wkt) wkt = find(evlrs, "LASF_Projection", 2112);
  if (wkt) {
    crs.wkt.assign(wkt->data.begin(), wkt->data.end());
    crs.wkt.erase(std::find(crs.wkt.begin(), crs.wkt.end(), '\0'), crs.wkt.end());
    const size_t first = crs.wkt.find_first_not_of(" \t\r\n");
    crs.wkt.erase(0, first == std::string::npos ? crs.wkt.size() : first);
    while (!crs.wkt.empty() && std::isspace(static_cast<unsigned char>(crs.wkt.back())))
      crs.wkt.pop_back();
    crs.blank_wkt = crs.wkt.empty();
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

  // One source decides; the other is only compared with it.
  const bool wkt_bit = (global_encoding & 16) != 0;
  const CrsFacts keys =
      crs.geokeys.empty() ? CrsFacts{} : geotiff_facts(crs.geokeys, resolve_names);
  const bool keys_decide = !crs.geokeys.empty() && (crs.wkt.empty() || (!wkt_bit && keys.epsg > 0));
  CrsFacts chosen;
  if (keys_decide) {
    crs.source = Crs::Source::GeoTiff;
    chosen = keys;
  } else if (!crs.wkt.empty()) {
    crs.source = Crs::Source::Wkt;
    chosen = wkt_facts(crs.wkt, resolve_names);
    crs.wkt_readable = chosen.readable;
  }
  if (!crs.wkt.empty() && keys.epsg > 0) {
    const CrsFacts other = keys_decide ? wkt_facts(crs.wkt, resolve_names) : keys;
    const int wkt_epsg = keys_decide ? other.epsg : chosen.epsg;
    if (wkt_epsg > 0 && wkt_epsg != keys.epsg)
      crs.conflict = fmt::format(
          "the WKT says EPSG:{} and the GeoTIFF keys EPSG:{}: the {} used (the header's WKT bit "
          "is {})",
          wkt_epsg, keys.epsg, keys_decide ? "GeoTIFF keys are" : "WKT is",
          wkt_bit ? "set" : "clear");
  }
  crs.epsg = chosen.epsg;
  crs.vertical_epsg = chosen.vertical_epsg;
  crs.geographic = chosen.geographic;
  crs.name = chosen.name;
  crs.linear_unit = crs.geographic ? "degree" : chosen.linear_unit;
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
