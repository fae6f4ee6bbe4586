// glTF splats: mode-POINTS primitives with KHR_gaussian_splatting attributes, uncompressed or
// SPZ-compressed (KHR_gaussian_splatting_compression_spz_2 nested in the base extension, or the
// older top-level KHR_spz_gaussian_splats_compression that CesiumJS still reads, whose
// attributes are named _SCALE, _ROTATION, ...).
#include <algorithm>
#include <map>
#include <set>

#include <glm/gtc/matrix_transform.hpp>
#include <glm/gtc/quaternion.hpp>
#include <nlohmann/json.hpp>

#include "gltf_nodes.hpp"
#include "splat_detail.hpp"

namespace stipple::io {
namespace {

using json = nlohmann::json;
using namespace splat_detail;

constexpr uint32_t kChunkJson = 0x4E4F534A, kChunkBin = 0x004E4942;

struct Glb {
  json j;
  std::string_view name;
  std::span<const uint8_t> bin;

  size_t index(const json& o, const char* key, size_t size, const char* what) const {
    auto it = o.find(key);
    if (it == o.end() || !it->is_number_unsigned() || it->get<uint64_t>() >= size)
      fail("{}: {} has no valid {}", name, what, key);
    return it->get<size_t>();
  }
  uint64_t number(const json& o, const char* key, uint64_t fallback, const char* what) const {
    auto it = o.find(key);
    if (it == o.end()) return fallback;
    if (!it->is_number_unsigned()) fail("{}: {} {} is not a non-negative integer", name, what, key);
    return it->get<uint64_t>();
  }

  // Buffer view `v` of the GLB's binary chunk (external and data: buffers are not read here).
  std::span<const uint8_t> view(size_t v, uint64_t& stride) const {
    const json& views = j.at("bufferViews");
    const json& bv = views.at(v);
    const json& buffers = j.at("buffers");
    const size_t b = index(bv, "buffer", buffers.size(), "a bufferView");
    if (b != 0 || buffers.at(b).contains("uri"))
      fail("{}: splat data in an external or data: buffer is not supported", name);
    const uint64_t offset = number(bv, "byteOffset", 0, "bufferView");
    const uint64_t length = number(bv, "byteLength", 0, "bufferView");
    stride = number(bv, "byteStride", 0, "bufferView");
    if (offset > bin.size() || bin.size() - offset < length)
      fail("{}: bufferView {} ({} bytes at {}) lies outside the binary chunk ({} bytes)", name, v,
           length, offset, bin.size());
    return bin.subspan(size_t(offset), size_t(length));
  }

  size_t count(size_t accessor) const {
    return size_t(number(j.at("accessors").at(accessor), "count", 0, "accessor"));
  }

  // Accessor `a` as floats (normalized integers to [0,1] / [-1,1]), `components` a value.
  std::vector<float> floats(size_t a, int components, const char* what) const {
    const json& acc = j.at("accessors").at(a);
    static const std::map<std::string, int> types = {
        {"SCALAR", 1}, {"VEC2", 2}, {"VEC3", 3}, {"VEC4", 4}};
    const std::string type = acc.value("type", "");
    auto t = types.find(type);
    if (t == types.end() || t->second != components)
      fail("{}: {} is {}, not {} components", name, what, type, components);
    const uint64_t ct = number(acc, "componentType", 0, "accessor");
    const int size = ct == 5126 || ct == 5125 ? 4 : ct == 5122 || ct == 5123 ? 2 : 1;
    if (ct < 5120 || ct > 5126 || ct == 5124)
      fail("{}: {} has unsupported componentType {}", name, what, ct);
    const bool normalized = acc.value("normalized", false);
    const uint64_t n = number(acc, "count", 0, "accessor");
    std::vector<float> out(size_t(n) * size_t(components), 0.0f);
    if (!acc.contains("bufferView")) return out;
    if (acc.contains("sparse")) fail("{}: {} is sparse, which is not supported", name, what);
    uint64_t stride = 0;
    auto data = view(index(acc, "bufferView", j.at("bufferViews").size(), "accessor"), stride);
    const uint64_t offset = number(acc, "byteOffset", 0, "accessor");
    const uint64_t elem = uint64_t(size) * uint64_t(components);
    if (stride == 0) stride = elem;
    if (stride < elem) fail("{}: {} stride {} is less than its element", name, what, stride);
    if (n > 0 && (offset > data.size() || data.size() - offset < elem ||
                  (data.size() - offset - elem) / stride < n - 1))
      fail("{}: {} ({} elements) runs past its bufferView", name, what, n);
    for (size_t i = 0; i < n; ++i)
      for (int k = 0; k < components; ++k) {
        const uint8_t* p = data.data() + offset + i * stride + size_t(k * size);
        float x;
        switch (ct) {
          case 5120:
            x = normalized ? std::max(float(int8_t(*p)) / 127.0f, -1.0f) : float(int8_t(*p));
            break;
          case 5121:
            x = normalized ? float(*p) / 255.0f : float(*p);
            break;
          case 5122:
            x = normalized ? std::max(float(int16_t(u16(p))) / 32767.0f, -1.0f)
                           : float(int16_t(u16(p)));
            break;
          case 5123:
            x = normalized ? float(u16(p)) / 65535.0f : float(u16(p));
            break;
          case 5125:
            x = float(u32(p));
            break;
          default:
            x = f32(p);
        }
        out[i * size_t(components) + size_t(k)] = x;
      }
    return out;
  }
};

// The attribute named `suffix` under the current or the older naming.
const json* splat_attribute(const json& attrs, const std::string& suffix) {
  for (const std::string& key : {"KHR_gaussian_splatting:" + suffix, "_" + suffix})
    if (auto it = attrs.find(key); it != attrs.end()) return &*it;
  return nullptr;
}

void append(SplatSet& all, SplatSet&& part) {
  if (all.positions.empty() && all.sh_degree == 0) {
    const glm::dmat4 t = all.transform;
    std::string format = all.format;
    all = std::move(part);
    all.transform = t;
    if (!format.empty()) all.format = format;
    return;
  }
  const int degree = std::max(all.sh_degree, part.sh_degree);
  auto widen = [&](SplatSet& s) {
    if (s.sh_degree == degree) return;
    SplatSet w = s;
    w.sh_degree = degree;
    w.sh_rest.assign(w.size() * w.rest_count(), glm::vec3(0.0f));
    for (size_t i = 0; i < s.size(); ++i)
      for (size_t k = 0; k < s.rest_count(); ++k)
        w.sh_rest[i * w.rest_count() + k] = s.sh_rest[i * s.rest_count() + k];
    s = std::move(w);
  };
  widen(all);
  widen(part);
  append_splats(all, part);
}

SplatSet decode_primitive(const Glb& g, const json& prim, const SplatLimits& limits,
                          bool& compressed) {
  const std::string_view name = g.name;
  const json& attrs = prim.value("attributes", json::object());
  if (!attrs.is_object() || !attrs.contains("POSITION"))
    fail("{}: a splat primitive has no POSITION", name);
  const size_t accessors = g.j.value("accessors", json::array()).size();
  auto accessor_of = [&](const json& ref, const char* what) {
    if (!ref.is_number_unsigned() || ref.get<uint64_t>() >= accessors)
      fail("{}: attribute {} names no accessor", name, what);
    return ref.get<size_t>();
  };
  const size_t pos = accessor_of(attrs.at("POSITION"), "POSITION");
  const size_t n = g.count(pos);
  if (n > limits.max_splats)
    fail("{}: {} splats exceed the limit of {}", name, n, limits.max_splats);

  // SPZ compression: the nested current extension or the older top-level one.
  const json ext = prim.value("extensions", json::object());
  const json* spz = nullptr;
  if (ext.is_object()) {
    if (auto base = ext.find("KHR_gaussian_splatting"); base != ext.end() && base->is_object() &&
                                                        base->contains("extensions") &&
                                                        (*base)["extensions"].is_object()) {
      const json& nested = (*base)["extensions"];
      for (const char* key :
           {"KHR_gaussian_splatting_compression_spz_2", "KHR_gaussian_splatting_compression_spz"})
        if (nested.contains(key)) spz = &nested[key];
    }
    if (!spz && ext.contains("KHR_spz_gaussian_splats_compression"))
      spz = &ext["KHR_spz_gaussian_splats_compression"];
  }
  if (spz) {
    if (!spz->is_object()) fail("{}: the SPZ compression extension is not an object", name);
    uint64_t stride = 0;
    auto data = g.view(g.index(*spz, "bufferView", g.j.value("bufferViews", json::array()).size(),
                               "the SPZ compression extension"),
                       stride);
    std::string spz_name = std::string(name) + " (SPZ)";
    SplatSet s = decode_spz(data, spz_name, limits);
    if (s.size() != n)
      fail("{}: the SPZ data holds {} splats, POSITION's accessor {}", name, s.size(), n);
    compressed = true;
    s.format.clear();
    return s;
  }

  auto required = [&](const char* suffix, int components) {
    const json* a = splat_attribute(attrs, suffix);
    if (!a) fail("{}: a splat primitive lacks KHR_gaussian_splatting:{}", name, suffix);
    auto v = g.floats(accessor_of(*a, suffix), components, suffix);
    if (v.size() != n * size_t(components))
      fail("{}: {} has a count other than POSITION's", name, suffix);
    return v;
  };
  auto optional = [&](const char* suffix, int components) -> std::vector<float> {
    const json* a = splat_attribute(attrs, suffix);
    if (!a) return {};
    auto v = g.floats(accessor_of(*a, suffix), components, suffix);
    if (v.size() != n * size_t(components))
      fail("{}: {} has a count other than POSITION's", name, suffix);
    return v;
  };
  int degree = 0;
  for (int l = 1; l <= 3; ++l)
    if (splat_attribute(attrs, fmt::format("SH_DEGREE_{}_COEF_0", l))) degree = l;
  SplatSet s;
  resize_splats(s, n, degree, limits, name);
  const auto positions = g.floats(pos, 3, "POSITION");
  const auto rot = required("ROTATION", 4);
  const auto scale = required("SCALE", 3);
  const auto opacity = optional("OPACITY", 1);
  const auto dc = optional("SH_DEGREE_0_COEF_0", 3);
  std::vector<float> colour;
  int colour_k = 0;
  if (attrs.contains("COLOR_0")) {
    const size_t c = accessor_of(attrs.at("COLOR_0"), "COLOR_0");
    colour_k = g.j.at("accessors").at(c).value("type", "") == "VEC4" ? 4 : 3;
    colour = g.floats(c, colour_k, "COLOR_0");
    if (colour.size() != n * size_t(colour_k))
      fail("{}: COLOR_0 has a count other than POSITION's", name);
  }
  if (dc.empty() && colour.empty())
    fail("{}: a splat primitive has neither SH_DEGREE_0_COEF_0 nor COLOR_0", name);
  if (opacity.empty() && colour_k != 4)
    fail("{}: a splat primitive has neither OPACITY nor an RGBA COLOR_0", name);
  const size_t rc = s.rest_count();
  for (size_t i = 0; i < n; ++i) {
    s.positions[i] = {positions[3 * i], positions[3 * i + 1], positions[3 * i + 2]};
    s.rotations[i] = unit_quaternion(rot[4 * i], rot[4 * i + 1], rot[4 * i + 2], rot[4 * i + 3]);
    s.scales[i] = {scale[3 * i], scale[3 * i + 1], scale[3 * i + 2]};
    s.opacities[i] = opacity.empty() ? colour[4 * i + 3] : opacity[i];
    if (!dc.empty())
      s.sh_dc[i] = {dc[3 * i], dc[3 * i + 1], dc[3 * i + 2]};
    else
      for (int c = 0; c < 3; ++c)
        s.sh_dc[i][c] = (colour[size_t(colour_k) * i + size_t(c)] - 0.5f) / kShC0;
  }
  size_t k = 0;
  for (int l = 1; l <= degree; ++l)
    for (int c = 0; c < 2 * l + 1; ++c, ++k) {
      const std::string key = fmt::format("SH_DEGREE_{}_COEF_{}", l, c);
      if (!splat_attribute(attrs, key)) fail("{}: {} is missing", name, key);
      const auto v = required(key.c_str(), 3);
      for (size_t i = 0; i < n; ++i) s.sh_rest[i * rc + k] = {v[3 * i], v[3 * i + 1], v[3 * i + 2]};
    }
  return s;
}

SplatSet decode_glb_unchecked(std::span<const uint8_t> data, std::string_view name,
                              const SplatLimits& limits) {
  Glb g;
  g.name = name;
  if (data.size() < 20 || std::memcmp(data.data(), "glTF", 4) != 0)
    fail("{}: not a GLB (no glTF header)", name);
  const uint32_t version = u32(data.data() + 4), length = u32(data.data() + 8);
  if (version != 2) fail("{}: GLB version {} is not supported", name, version);
  if (length != data.size())
    fail("{}: GLB length {} does not match its {} bytes (truncated?)", name, length, data.size());
  std::span<const uint8_t> json_chunk;
  for (size_t at = 12; at + 8 <= data.size();) {
    const uint32_t chunk = u32(data.data() + at), type = u32(data.data() + at + 4);
    at += 8;
    if (chunk > data.size() - at) fail("{}: GLB chunk of {} bytes runs past the end", name, chunk);
    if (type == kChunkJson && json_chunk.empty()) json_chunk = data.subspan(at, chunk);
    if (type == kChunkBin && g.bin.empty()) g.bin = data.subspan(at, chunk);
    at += chunk;
  }
  if (json_chunk.empty()) fail("{}: GLB has no JSON chunk", name);
  g.j = json::parse(json_chunk.begin(), json_chunk.end(), nullptr, false);
  if (g.j.is_discarded() || !g.j.is_object()) fail("{}: glTF JSON is not valid", name);
  const json& j = g.j;
  for (const char* key : {"accessors", "bufferViews", "buffers", "meshes", "nodes"})
    if (j.contains(key) && !j[key].is_array()) fail("{}: {} is not an array", name, key);
  static const std::set<std::string> supported = {"KHR_gaussian_splatting",
                                                  "KHR_gaussian_splatting_compression_spz_2",
                                                  "KHR_gaussian_splatting_compression_spz",
                                                  "KHR_spz_gaussian_splats_compression",
                                                  "KHR_materials_unlit",
                                                  "KHR_mesh_quantization",
                                                  "CESIUM_RTC"};
  if (auto req = j.find("extensionsRequired"); req != j.end() && req->is_array())
    for (const auto& e : *req)
      if (!e.is_string() || !supported.count(e.get<std::string>()))
        fail("{}: requires glTF extension {}, which the splat reader does not support", name,
             e.dump());

  glm::dvec3 rtc(0.0);
  if (auto e = j.find("extensions"); e != j.end() && e->is_object() && e->contains("CESIUM_RTC")) {
    const json& c = (*e)["CESIUM_RTC"].value("center", json());
    if (!c.is_array() || c.size() != 3 || !c[0].is_number() || !c[1].is_number() ||
        !c[2].is_number())
      fail("{}: CESIUM_RTC center is not three numbers", name);
    rtc = {c[0].get<double>(), c[1].get<double>(), c[2].get<double>()};
  }

  const json meshes = j.value("meshes", json::array());
  SplatSet all;
  all.format = "glTF KHR_gaussian_splatting";
  bool have_matrix = false, compressed = false;
  for (const gltf_nodes::MeshNode& mn : gltf_nodes::mesh_nodes(j, name)) {
    const glm::dmat4& m = mn.world;
    const json& mesh = meshes[mn.mesh];
    if (!mesh.is_object()) fail("{}: mesh is not an object", name);
    for (const auto& prim : mesh.value("primitives", json::array())) {
      if (!prim.is_object() || prim.value("mode", int64_t(4)) != 0) continue;
      const json attrs = prim.value("attributes", json::object());
      const json ext = prim.value("extensions", json::object());
      const bool splat = (attrs.is_object() && splat_attribute(attrs, "ROTATION")) ||
                         (ext.is_object() && (ext.contains("KHR_gaussian_splatting") ||
                                              ext.contains("KHR_spz_gaussian_splats_compression")));
      if (!splat) continue;
      if (have_matrix && m != all.transform)
        fail("{}: splat primitives under different node transforms are not supported", name);
      all.transform = m;
      have_matrix = true;
      append(all, decode_primitive(g, prim, limits, compressed));
      if (all.size() > limits.max_splats) fail("{}: more than {} splats", name, limits.max_splats);
    }
  }
  if (!have_matrix) fail("{}: the glTF holds no KHR_gaussian_splatting primitive", name);
  if (compressed) all.format += " (SPZ)";
  // CESIUM_RTC is a translation in the Z-up tile frame, after the Y-up to Z-up rotation:
  // in the Y-up frame of `transform` it is (x, z, -y).
  if (rtc != glm::dvec3(0.0))
    all.transform =
        glm::translate(glm::dmat4(1.0), glm::dvec3(rtc.x, rtc.z, -rtc.y)) * all.transform;
  return all;
}

}  // namespace

SplatSet decode_splats_glb(std::span<const uint8_t> glb, std::string_view name,
                           const SplatLimits& limits) {
  try {
    SplatSet s = decode_glb_unchecked(glb, name, limits);
    check_values(s, name);
    return s;
  } catch (const nlohmann::json::exception& e) {
    fail("{}: malformed glTF JSON: {}", name, e.what());
  }
}

}  // namespace stipple::io
