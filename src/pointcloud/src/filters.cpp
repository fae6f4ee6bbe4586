#include "stipple/pointcloud/filters.hpp"

#include <cmath>
#include <stdexcept>

#include <fmt/format.h>

#include "stipple/core/error.hpp"
#include "stipple/math/camera.hpp"

namespace stipple::pc {

void PointFilter::set_class(uint32_t c, bool kept) {
  if (c >= 256) return;
  if (kept)
    classes[c / 32] |= 1u << (c % 32);
  else
    classes[c / 32] &= ~(1u << (c % 32));
}

bool PointFilter::filters_classes() const {
  for (uint32_t w : classes)
    if (w != ~0u) return true;
  return false;
}

bool PointFilter::active() const {
  return filters_classes() || returns != 0 || intensity || gps_time || point_source;
}

bool return_kind_matches(uint8_t kinds, uint32_t rn, uint32_t nr) {
  if (kinds == 0) return true;
  if ((kinds & kReturnFirst) && rn <= 1) return true;
  if ((kinds & kReturnLast) && rn >= nr) return true;
  if ((kinds & kReturnSingle) && nr <= 1) return true;
  if ((kinds & kReturnIntermediate) && rn > 1 && rn < nr) return true;
  return false;
}

bool PointFilter::accepts(uint32_t cls, uint32_t rn, uint32_t nr, uint32_t in, double gps,
                          uint32_t source) const {
  if (!class_kept(cls)) return false;
  if (!return_kind_matches(returns, rn, nr)) return false;
  if (intensity && (in < intensity->x || in > intensity->y)) return false;
  if (gps_time && (gps < gps_time->x || gps > gps_time->y)) return false;
  if (point_source && (source < point_source->x || source > point_source->y)) return false;
  return true;
}

bool PointFilter::accepts(const io::PointBatch& b, size_t i) const {
  return accepts(b.classification.empty() ? 1 : b.classification[i],
                 b.return_number.empty() ? 1 : b.return_number[i],
                 b.number_of_returns.empty() ? 1 : b.number_of_returns[i],
                 b.intensity.empty() ? 0 : b.intensity[i], b.gps_time.empty() ? 0.0 : b.gps_time[i],
                 b.point_source_id.empty() ? 0 : b.point_source_id[i]);
}

bool ClipBox::contains(const glm::dvec3& p) const {
  const glm::dvec3 d = p - center;
  const double c = std::cos(yaw), s = std::sin(yaw);
  // Into the box's frame: rotate by -yaw.
  const double lx = c * d.x + s * d.y, ly = -s * d.x + c * d.y;
  return std::abs(lx) <= half_size.x && std::abs(ly) <= half_size.y && std::abs(d.z) <= half_size.z;
}

std::array<glm::dvec3, 8> ClipBox::corners() const {
  const double c = std::cos(yaw), s = std::sin(yaw);
  const glm::dvec2 ax(c, s), ay(-s, c);
  static constexpr int kSigns[4][2] = {{-1, -1}, {1, -1}, {1, 1}, {-1, 1}};
  std::array<glm::dvec3, 8> out;
  for (int i = 0; i < 8; ++i) {
    const int k = i % 4;
    const glm::dvec2 xy =
        glm::dvec2(center) + ax * (kSigns[k][0] * half_size.x) + ay * (kSigns[k][1] * half_size.y);
    out[size_t(i)] = {xy.x, xy.y, center.z + (i < 4 ? -half_size.z : half_size.z)};
  }
  return out;
}

bool ClipPolygon::contains(const glm::dvec3& p) const {
  if (p.z < min_z || p.z > max_z) return false;
  bool inside = false;
  for (const auto& ring : rings) {
    const size_t n = ring.size();
    for (size_t i = 0, j = n - 1; i < n; j = i++) {
      const glm::dvec2 a = ring[i], b = ring[j];
      // Crossing of the horizontal ray to +X (half-open in y so vertices count once).
      if ((a.y > p.y) != (b.y > p.y) && p.x < (b.x - a.x) * (p.y - a.y) / (b.y - a.y) + a.x)
        inside = !inside;
    }
  }
  return inside;
}

bool ClipRegion::contains(const glm::dvec3& p) const {
  for (const ClipPlane& plane : planes)
    if (!plane.contains(p)) return false;
  if (boxes.empty() && polygons.empty()) return true;
  for (const ClipBox& box : boxes)
    if (box.contains(p)) return true;
  for (const ClipPolygon& polygon : polygons)
    if (polygon.contains(p)) return true;
  return false;
}

bool chunk_point_shown(const PointChunk& chunk, size_t i, const PointFilter& filter,
                       const ClipRegion& clip) {
  const PointChunk::Vertex& v = chunk.vertices[i];
  if (filter.active()) {
    const bool extras = chunk.extras.size() == chunk.vertices.size();
    if (!filter.class_kept((v.attributes >> 16) & 0xffu) ||
        !return_kind_matches(filter.returns, (v.attributes >> 24) & 0xfu, v.attributes >> 28))
      return false;
    const double in = v.attributes & 0xffffu;
    if (filter.intensity && (in < filter.intensity->x || in > filter.intensity->y)) return false;
    if (extras) {
      const double gps = chunk.gps_origin + double(chunk.extras[i].gps);
      const double source = chunk.extras[i].word & 0xffffu;
      if (filter.gps_time && (gps < filter.gps_time->x || gps > filter.gps_time->y)) return false;
      if (filter.point_source &&
          (source < filter.point_source->x || source > filter.point_source->y))
        return false;
    }
  }
  if (clip.empty() || clip.mode == ClipMode::Highlight) return true;
  return clip.keeps(y_up_to_z_up(chunk.origin + glm::dvec3(v.x, v.y, v.z)));
}

ClipMode parse_clip_mode(const std::string& name) {
  if (name == "inside") return ClipMode::Inside;
  if (name == "outside") return ClipMode::Outside;
  if (name == "highlight") return ClipMode::Highlight;
  fail("unknown clip mode '{}' (inside, outside, highlight)", name);
}

const char* clip_mode_name(ClipMode mode) {
  switch (mode) {
    case ClipMode::Outside:
      return "outside";
    case ClipMode::Highlight:
      return "highlight";
    default:
      return "inside";
  }
}

namespace {

std::vector<std::string> split(const std::string& text, char sep) {
  std::vector<std::string> parts;
  size_t start = 0;
  while (true) {
    const size_t at = text.find(sep, start);
    parts.push_back(text.substr(start, at == std::string::npos ? std::string::npos : at - start));
    if (at == std::string::npos) break;
    start = at + 1;
  }
  return parts;
}

std::string trim(const std::string& s) {
  const size_t a = s.find_first_not_of(" \t"), b = s.find_last_not_of(" \t");
  return a == std::string::npos ? std::string() : s.substr(a, b - a + 1);
}

double number(const std::string& part, const std::string& text, const char* flag) {
  const std::string t = trim(part);
  try {
    size_t used = 0;
    const double v = std::stod(t, &used);
    if (used == t.size() && std::isfinite(v)) return v;
  } catch (const std::exception&) {
  }
  fail("{} '{}': '{}' is not a finite number", flag, text, t);
}

std::vector<double> numbers(const std::string& text, const char* flag) {
  std::vector<double> out;
  for (const std::string& part : split(text, ',')) out.push_back(number(part, text, flag));
  return out;
}

uint32_t class_number(const std::string& part, const std::string& text, const char* flag) {
  const std::string t = trim(part);
  size_t used = 0;
  long v = -1;
  try {
    v = std::stol(t, &used);
  } catch (const std::exception&) {
    used = 0;
  }
  if (used != t.size() || t.empty()) fail("{} '{}': '{}' is not a class number", flag, text, t);
  if (v < 0 || v > 255)
    fail("{} '{}': class {} is out of range (LAS classes are 0-255)", flag, text, v);
  return uint32_t(v);
}

}  // namespace

std::array<uint32_t, 8> parse_classes(const std::string& text, const char* flag) {
  std::array<uint32_t, 8> mask{};
  if (trim(text).empty()) fail("{}: no classes given", flag);
  for (const std::string& part : split(text, ',')) {
    const size_t dash = part.find('-', part.find_first_not_of(" \t") + 1);
    uint32_t lo, hi;
    if (dash != std::string::npos) {
      lo = class_number(part.substr(0, dash), text, flag);
      hi = class_number(part.substr(dash + 1), text, flag);
      if (lo > hi) fail("{} '{}': range {}-{} runs backwards", flag, text, lo, hi);
    } else {
      lo = hi = class_number(part, text, flag);
    }
    for (uint32_t c = lo; c <= hi; ++c) mask[c / 32] |= 1u << (c % 32);
  }
  return mask;
}

uint8_t parse_returns(const std::string& text, const char* flag) {
  uint8_t kinds = 0;
  for (const std::string& part : split(text, ',')) {
    const std::string t = trim(part);
    if (t == "first")
      kinds |= kReturnFirst;
    else if (t == "last")
      kinds |= kReturnLast;
    else if (t == "single")
      kinds |= kReturnSingle;
    else if (t == "intermediate")
      kinds |= kReturnIntermediate;
    else
      fail("{} '{}': unknown return kind '{}' (first, last, single, intermediate)", flag, text, t);
  }
  return kinds;
}

glm::dvec2 parse_range(const std::string& text, const char* flag) {
  const std::vector<double> v = numbers(text, flag);
  if (v.size() != 2) fail("{} '{}': expected 'min,max', got {} numbers", flag, text, v.size());
  if (v[0] > v[1]) fail("{} '{}': min {} is greater than max {}", flag, text, v[0], v[1]);
  return {v[0], v[1]};
}

ClipBox parse_box(const std::string& text, const char* flag) {
  const std::vector<double> v = numbers(text, flag);
  if (v.size() != 6 && v.size() != 7)
    fail("{} '{}': expected 'minx,miny,minz,maxx,maxy,maxz[,yaw_degrees]', got {} numbers", flag,
         text, v.size());
  for (int i = 0; i < 3; ++i)
    if (v[size_t(i)] > v[size_t(i) + 3])
      fail("{} '{}': min{} {} is greater than max{} {}", flag, text, "xyz"[i], v[size_t(i)],
           "xyz"[i], v[size_t(i) + 3]);
  ClipBox box;
  box.center = {(v[0] + v[3]) / 2, (v[1] + v[4]) / 2, (v[2] + v[5]) / 2};
  box.half_size = {(v[3] - v[0]) / 2, (v[4] - v[1]) / 2, (v[5] - v[2]) / 2};
  if (v.size() == 7) box.yaw = v[6] * M_PI / 180.0;
  return box;
}

ClipPlane parse_plane(const std::string& text, const char* flag) {
  const std::vector<double> v = numbers(text, flag);
  if (v.size() != 4) fail("{} '{}': expected 'a,b,c,d' (a*x + b*y + c*z + d >= 0)", flag, text);
  const glm::dvec3 n(v[0], v[1], v[2]);
  const double length = std::sqrt(n.x * n.x + n.y * n.y + n.z * n.z);
  if (!(length > 0)) fail("{} '{}': the normal (a,b,c) is zero", flag, text);
  return {n / length, v[3] / length};
}

std::string classification_name(uint32_t c) {
  static constexpr const char* kNames[] = {"created, never classified",
                                           "unclassified",
                                           "ground",
                                           "low vegetation",
                                           "medium vegetation",
                                           "high vegetation",
                                           "building",
                                           "low point (noise)",
                                           "reserved (model key-point)",
                                           "water",
                                           "rail",
                                           "road surface",
                                           "reserved (overlap)",
                                           "wire guard (shield)",
                                           "wire conductor (phase)",
                                           "transmission tower",
                                           "wire-structure connector",
                                           "bridge deck",
                                           "high noise",
                                           "overhead structure",
                                           "ignored ground",
                                           "snow",
                                           "temporal exclusion"};
  if (c < std::size(kNames)) return kNames[c];
  if (c < 64) return "reserved";
  return "user defined";
}

}  // namespace stipple::pc
