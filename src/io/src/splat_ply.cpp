// The two PLY splat layouts: INRIA's (one vertex element of scalar properties, in the trainer's
// pre-activation units) and PlayCanvas's compressed one (chunks of 256 splats with min/max
// ranges, four packed words a splat, optional 8-bit SH).
#include <algorithm>
#include <map>
#include <optional>
#include <string>

#include "splat_detail.hpp"

namespace stipple::io::splat_detail {
namespace {

struct PlyProperty {
  std::string name;
  int size = 0;       // bytes
  char kind = 'f';    // 'i' signed, 'u' unsigned, 'f' float
  size_t offset = 0;  // within the element's record
};

struct PlyElement {
  std::string name;
  uint64_t count = 0;
  std::vector<PlyProperty> properties;
  size_t stride = 0;
  size_t data_offset = 0;  // from the start of the file

  const PlyProperty* find(std::string_view p) const {
    for (const auto& q : properties)
      if (q.name == p) return &q;
    return nullptr;
  }
};

struct PlyHeader {
  std::string format;
  std::vector<PlyElement> elements;
  size_t header_size = 0;
  const PlyElement* find(std::string_view e) const {
    for (const auto& q : elements)
      if (q.name == e) return &q;
    return nullptr;
  }
};

bool scalar_type(const std::string& t, int& size, char& kind) {
  static const std::map<std::string, std::pair<int, char>> types = {
      {"char", {1, 'i'}},  {"int8", {1, 'i'}},    {"uchar", {1, 'u'}},  {"uint8", {1, 'u'}},
      {"short", {2, 'i'}}, {"int16", {2, 'i'}},   {"ushort", {2, 'u'}}, {"uint16", {2, 'u'}},
      {"int", {4, 'i'}},   {"int32", {4, 'i'}},   {"uint", {4, 'u'}},   {"uint32", {4, 'u'}},
      {"float", {4, 'f'}}, {"float32", {4, 'f'}}, {"double", {8, 'f'}}, {"float64", {8, 'f'}}};
  auto it = types.find(t);
  if (it == types.end()) return false;
  size = it->second.first;
  kind = it->second.second;
  return true;
}

// Parses the header; with `strict`, unsupported content is an error, else only the structure
// is read as far as it goes (for the format check of is_splat_path, on a truncated head).
std::optional<PlyHeader> parse_header(std::span<const uint8_t> bytes, std::string_view name,
                                      bool strict) {
  std::string_view text(reinterpret_cast<const char*>(bytes.data()),
                        std::min<size_t>(bytes.size(), 1 << 20));
  size_t end = text.find("end_header");
  if (end == std::string_view::npos) {
    if (strict) fail("{}: PLY header has no end_header (truncated or not PLY)", name);
    return std::nullopt;
  }
  size_t eol = text.find('\n', end);
  if (eol == std::string_view::npos) {
    if (strict) fail("{}: PLY header ends without a newline", name);
    return std::nullopt;
  }
  PlyHeader h;
  h.header_size = eol + 1;
  size_t at = 0;
  while (at < end) {
    size_t nl = text.find('\n', at);
    std::string_view line = text.substr(at, nl - at);
    at = nl + 1;
    if (!line.empty() && line.back() == '\r') line.remove_suffix(1);
    std::vector<std::string> words;
    size_t w = 0;
    while (w < line.size()) {
      size_t s = line.find_first_not_of(" \t", w);
      if (s == std::string_view::npos) break;
      size_t e = line.find_first_of(" \t", s);
      if (e == std::string_view::npos) e = line.size();
      words.emplace_back(line.substr(s, e - s));
      w = e;
    }
    if (words.empty()) continue;
    if (words[0] == "format" && words.size() >= 2) {
      h.format = words[1];
    } else if (words[0] == "element" && words.size() >= 3) {
      PlyElement e;
      e.name = words[1];
      try {
        size_t used = 0;
        e.count = std::stoull(words[2], &used);
        if (used != words[2].size() || words[2][0] == '-') throw std::invalid_argument("count");
      } catch (const std::exception&) {
        if (strict) fail("{}: PLY element {} has an invalid count '{}'", name, e.name, words[2]);
        return std::nullopt;
      }
      h.elements.push_back(std::move(e));
    } else if (words[0] == "property") {
      if (h.elements.empty()) {
        if (strict) fail("{}: PLY property before any element", name);
        return std::nullopt;
      }
      PlyElement& e = h.elements.back();
      if (words.size() >= 2 && words[1] == "list") {
        if (strict)
          fail("{}: PLY element {} has a list property, which splat files do not hold", name,
               e.name);
        e.properties.push_back({words.back(), 0, 'l', 0});
        continue;
      }
      PlyProperty p;
      if (words.size() < 3 || !scalar_type(words[1], p.size, p.kind)) {
        if (strict) fail("{}: PLY property '{}' has an unknown type", name, std::string(line));
        return std::nullopt;
      }
      p.name = words[2];
      p.offset = e.stride;
      e.stride += size_t(p.size);
      e.properties.push_back(std::move(p));
    }
  }
  return h;
}

bool is_inria(const PlyHeader& h) {
  const PlyElement* v = h.find("vertex");
  return v && v->find("f_dc_0") && v->find("opacity") && v->find("scale_0") && v->find("rot_0");
}

bool is_compressed(const PlyHeader& h) {
  const PlyElement* v = h.find("vertex");
  return h.find("chunk") && v && v->find("packed_position");
}

double load(const uint8_t* p, const PlyProperty& q) {
  switch (q.kind) {
    case 'u':
      return q.size == 1 ? p[0] : q.size == 2 ? u16(p) : u32(p);
    case 'i':
      return q.size == 1   ? double(int8_t(p[0]))
             : q.size == 2 ? double(int16_t(u16(p)))
                           : double(int32_t(u32(p)));
    default:
      if (q.size == 4) return f32(p);
      double d;
      std::memcpy(&d, p, 8);
      return d;
  }
}

// Lays the elements out one after another and checks each fits in the file.
void place_elements(PlyHeader& h, size_t file_size, std::string_view name) {
  size_t at = h.header_size;
  for (auto& e : h.elements) {
    e.data_offset = at;
    if (e.count == 0) continue;
    if (e.stride == 0) fail("{}: PLY element {} has records of no size", name, e.name);
    const size_t left = file_size - std::min(file_size, at);
    if (e.count > left / e.stride)
      fail("{}: PLY element {} ({} records of {} bytes) runs past the end of the file ({} bytes)",
           name, e.name, e.count, e.stride, file_size);
    at += size_t(e.count) * e.stride;
  }
}

const PlyProperty& need(const PlyElement& e, const std::string& p, std::string_view name) {
  const PlyProperty* q = e.find(p);
  if (!q) fail("{}: PLY element {} lacks property {}", name, e.name, p);
  return *q;
}

int degree_of_rest(size_t rest_per_channel, std::string_view name) {
  switch (rest_per_channel) {
    case 0:
      return 0;
    case 3:
      return 1;
    case 8:
      return 2;
    case 15:
      return 3;
    default:
      fail("{}: {} f_rest values a channel match no SH degree up to 3", name, rest_per_channel);
  }
}

// f_rest_0.. as a list of properties; their count must be a multiple of three.
std::vector<const PlyProperty*> rest_properties(const PlyElement& e, std::string_view name) {
  std::vector<const PlyProperty*> rest;
  while (const PlyProperty* q = e.find("f_rest_" + std::to_string(rest.size()))) rest.push_back(q);
  if (rest.size() % 3 != 0)
    fail("{}: {} f_rest properties are not a multiple of three", name, rest.size());
  return rest;
}

SplatSet decode_inria(const PlyHeader& h, std::span<const uint8_t> bytes, std::string_view name,
                      const SplatLimits& limits) {
  const PlyElement& v = *h.find("vertex");
  auto rest = rest_properties(v, name);
  const size_t per_channel = rest.size() / 3;
  SplatSet s;
  s.format = "INRIA PLY";
  resize_splats(s, size_t(v.count), degree_of_rest(per_channel, name), limits, name);
  const PlyProperty* p[14];
  const char* names[14] = {"x",       "y",       "z",       "f_dc_0", "f_dc_1", "f_dc_2", "opacity",
                           "scale_0", "scale_1", "scale_2", "rot_0",  "rot_1",  "rot_2",  "rot_3"};
  for (int k = 0; k < 14; ++k) p[k] = &need(v, names[k], name);
  const size_t rc = s.rest_count();
  for (size_t i = 0; i < s.size(); ++i) {
    const uint8_t* r = bytes.data() + v.data_offset + i * v.stride;
    auto get = [&](int k) { return float(load(r + p[k]->offset, *p[k])); };
    s.positions[i] = {get(0), get(1), get(2)};
    s.sh_dc[i] = {get(3), get(4), get(5)};
    s.opacities[i] = sigmoid(get(6));
    s.scales[i] = {std::exp(get(7)), std::exp(get(8)), std::exp(get(9))};
    // rot_0 is the real part.
    s.rotations[i] = unit_quaternion(get(11), get(12), get(13), get(10));
    // f_rest is channel-major in the file (all R coefficients, then G, then B).
    for (size_t j = 0; j < rest.size(); ++j)
      s.sh_rest[i * rc + j % per_channel][int(j / per_channel)] =
          float(load(r + rest[j]->offset, *rest[j]));
  }
  return s;
}

// 11-10-11 bits to [0, 1]^3.
glm::vec3 unpack_111011(uint32_t v) {
  return {float((v >> 21) & 0x7ff) / 2047.0f, float((v >> 11) & 0x3ff) / 1023.0f,
          float(v & 0x7ff) / 2047.0f};
}

// Two bits name the largest component (in rot_0..rot_3 order, rot_0 the real part), three
// 10-bit values the others in [-1/sqrt2, 1/sqrt2]. Returned as (x, y, z, w).
glm::vec4 unpack_rotation(uint32_t v) {
  const float norm = 1.0f / (std::sqrt(2.0f) * 0.5f);
  const float a = (float((v >> 20) & 0x3ff) / 1023.0f - 0.5f) * norm;
  const float b = (float((v >> 10) & 0x3ff) / 1023.0f - 0.5f) * norm;
  const float c = (float(v & 0x3ff) / 1023.0f - 0.5f) * norm;
  const float m = std::sqrt(std::max(0.0f, 1.0f - (a * a + b * b + c * c)));
  float q[4];  // rot_0..rot_3 = w, x, y, z
  switch (v >> 30) {
    case 0:
      q[0] = m, q[1] = a, q[2] = b, q[3] = c;
      break;
    case 1:
      q[0] = a, q[1] = m, q[2] = b, q[3] = c;
      break;
    case 2:
      q[0] = a, q[1] = b, q[2] = m, q[3] = c;
      break;
    default:
      q[0] = a, q[1] = b, q[2] = c, q[3] = m;
      break;
  }
  return unit_quaternion(q[1], q[2], q[3], q[0]);
}

SplatSet decode_compressed(const PlyHeader& h, std::span<const uint8_t> bytes,
                           std::string_view name, const SplatLimits& limits) {
  const PlyElement& chunk = *h.find("chunk");
  const PlyElement& v = *h.find("vertex");
  const PlyElement* sh = h.find("sh");
  if ((v.count + 255) / 256 > chunk.count)
    fail("{}: {} chunks cannot hold {} splats (256 a chunk)", name, chunk.count, v.count);
  const char* chunk_names[12] = {"min_x",       "min_y",       "min_z",       "max_x",
                                 "max_y",       "max_z",       "min_scale_x", "min_scale_y",
                                 "min_scale_z", "max_scale_x", "max_scale_y", "max_scale_z"};
  const PlyProperty* cp[18];
  for (int k = 0; k < 12; ++k) cp[k] = &need(chunk, chunk_names[k], name);
  // Older files have no colour ranges: the packed colour is then the colour itself.
  const char* colour_names[6] = {"min_r", "min_g", "min_b", "max_r", "max_g", "max_b"};
  const bool colour_range = chunk.find("min_r") != nullptr;
  if (colour_range)
    for (int k = 0; k < 6; ++k) cp[12 + k] = &need(chunk, colour_names[k], name);
  const PlyProperty* vp[4];
  const char* vertex_names[4] = {"packed_position", "packed_rotation", "packed_scale",
                                 "packed_color"};
  for (int k = 0; k < 4; ++k) {
    vp[k] = &need(v, vertex_names[k], name);
    if (vp[k]->size != 4 || vp[k]->kind != 'u')
      fail("{}: PLY property {} is not a uint", name, vertex_names[k]);
  }
  std::vector<const PlyProperty*> rest;
  if (sh) {
    if (sh->count != v.count)
      fail("{}: PLY element sh has {} records for {} splats", name, sh->count, v.count);
    rest = rest_properties(*sh, name);
    for (auto* q : rest)
      if (q->size != 1 || q->kind != 'u')
        fail("{}: PLY sh property {} is not uchar", name, q->name);
  }
  const size_t per_channel = rest.size() / 3;
  SplatSet s;
  s.format = "PlayCanvas compressed PLY";
  resize_splats(s, size_t(v.count), degree_of_rest(per_channel, name), limits, name);
  const size_t rc = s.rest_count();
  for (size_t i = 0; i < s.size(); ++i) {
    const uint8_t* c = bytes.data() + chunk.data_offset + (i / 256) * chunk.stride;
    auto cf = [&](int k) { return float(load(c + cp[k]->offset, *cp[k])); };
    const uint8_t* r = bytes.data() + v.data_offset + i * v.stride;
    const uint32_t pos = u32(r + vp[0]->offset), rot = u32(r + vp[1]->offset),
                   scl = u32(r + vp[2]->offset), col = u32(r + vp[3]->offset);
    const glm::vec3 tp = unpack_111011(pos), ts = unpack_111011(scl);
    s.positions[i] = glm::mix(glm::vec3(cf(0), cf(1), cf(2)), glm::vec3(cf(3), cf(4), cf(5)), tp);
    const glm::vec3 log_scale =
        glm::mix(glm::vec3(cf(6), cf(7), cf(8)), glm::vec3(cf(9), cf(10), cf(11)), ts);
    s.scales[i] = glm::exp(log_scale);
    s.rotations[i] = unpack_rotation(rot);
    glm::vec3 colour(float((col >> 24) & 0xff) / 255.0f, float((col >> 16) & 0xff) / 255.0f,
                     float((col >> 8) & 0xff) / 255.0f);
    if (colour_range)
      colour =
          glm::mix(glm::vec3(cf(12), cf(13), cf(14)), glm::vec3(cf(15), cf(16), cf(17)), colour);
    s.sh_dc[i] = (colour - 0.5f) / kShC0;
    s.opacities[i] = float(col & 0xff) / 255.0f;
    if (sh) {
      const uint8_t* q = bytes.data() + sh->data_offset + i * sh->stride;
      for (size_t j = 0; j < rest.size(); ++j) {
        const uint8_t b = q[rest[j]->offset];
        // 8 bits over [-4, 4); 0 and 255 are the ends exactly.
        const float n = b == 0 ? 0.0f : b == 255 ? 1.0f : (float(b) + 0.5f) / 256.0f;
        s.sh_rest[i * rc + j % per_channel][int(j / per_channel)] = (n - 0.5f) * 8.0f;
      }
    }
  }
  return s;
}

}  // namespace

bool is_splat_ply_header(std::span<const uint8_t> bytes) {
  if (bytes.size() < 4 || std::memcmp(bytes.data(), "ply", 3) != 0) return false;
  auto h = parse_header(bytes, "", false);
  return h && (is_inria(*h) || is_compressed(*h));
}

SplatSet decode_ply_splats(std::span<const uint8_t> bytes, std::string_view name,
                           const SplatLimits& limits) {
  PlyHeader h = *parse_header(bytes, name, true);
  if (h.format != "binary_little_endian")
    fail("{}: PLY format '{}' is not supported (splat PLY files are binary_little_endian)", name,
         h.format);
  const bool compressed = is_compressed(h);
  if (!compressed && !is_inria(h))
    fail(
        "{}: PLY file holds no splats (no f_dc_0/opacity/scale_0/rot_0 vertex properties, "
        "no compressed chunk element)",
        name);
  place_elements(h, bytes.size(), name);
  return compressed ? decode_compressed(h, bytes, name, limits)
                    : decode_inria(h, bytes, name, limits);
}

}  // namespace stipple::io::splat_detail
