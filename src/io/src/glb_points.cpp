#include "stipple/io/glb_points.hpp"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <map>
#include <set>

#include <meshoptimizer.h>
#include <glm/gtc/quaternion.hpp>
#include <glm/mat4x4.hpp>
#include <nlohmann/json.hpp>

#include "gltf_nodes.hpp"
#include "stipple/core/error.hpp"
#include "stipple/math/color.hpp"

namespace stipple::io {
namespace {

using json = nlohmann::json;
using detail::read_u32;

constexpr uint32_t kChunkJson = 0x4E4F534A, kChunkBin = 0x004E4942;

std::vector<uint8_t> decode_base64(std::string_view s, const std::string& name) {
  auto value = [](char c) -> int {
    if (c >= 'A' && c <= 'Z') return c - 'A';
    if (c >= 'a' && c <= 'z') return c - 'a' + 26;
    if (c >= '0' && c <= '9') return c - '0' + 52;
    if (c == '+' || c == '-') return 62;
    if (c == '/' || c == '_') return 63;
    return -1;
  };
  std::vector<uint8_t> out;
  out.reserve(s.size() / 4 * 3);
  uint32_t acc = 0;
  int bits = 0;
  for (char c : s) {
    if (c == '=') break;
    int v = value(c);
    if (v < 0) fail("{}: invalid base64 in a data: URI", name);
    acc = (acc << 6) | uint32_t(v);
    bits += 6;
    if (bits >= 8) {
      bits -= 8;
      out.push_back(uint8_t(acc >> bits));
    }
  }
  return out;
}

// Integer index `key` of object j, checked against [0, size).
size_t index_of(const json& j, const char* key, size_t size, const std::string& name,
                const char* what) {
  auto it = j.find(key);
  if (it == j.end() || !it->is_number_integer() || it->get<int64_t>() < 0 ||
      it->get<uint64_t>() >= size)
    fail("{}: {} has no valid {} (index out of range)", name, what, key);
  return it->get<size_t>();
}

uint64_t uint_of(const json& j, const char* key, uint64_t fallback, const std::string& name,
                 const char* what) {
  auto it = j.find(key);
  if (it == j.end()) return fallback;
  if (!it->is_number_integer() || it->get<int64_t>() < 0)
    fail("{}: {} {} is not a non-negative integer", name, what, key);
  return it->get<uint64_t>();
}

struct Gltf {
  json j;
  std::string name;
  DecodeLimits limits;
  std::vector<std::vector<uint8_t>> owned;  // buffers from data: URIs or the resolver
  std::vector<std::span<const uint8_t>> buffers;
  std::vector<std::span<const uint8_t>> views;  // resolved (decompressed) buffer views
  std::vector<uint32_t> view_strides;
  std::vector<std::string> warnings;

  void load_buffers(std::span<const uint8_t> bin, const BufferResolver& resolver) {
    const json& list = j.value("buffers", json::array());
    if (!list.is_array()) fail("{}: buffers is not an array", name);
    owned.reserve(list.size());
    for (size_t i = 0; i < list.size(); ++i) {
      const json& b = list[i];
      uint64_t length = uint_of(b, "byteLength", 0, name, "buffer");
      std::span<const uint8_t> data;
      if (!b.contains("uri")) {
        // A fallback buffer of EXT_meshopt_compression may have no data at all.
        if (i == 0 && !bin.empty()) {
          data = bin;
        } else {
          buffers.push_back({});
          continue;
        }
      } else {
        std::string uri = b["uri"].is_string() ? b["uri"].get<std::string>() : "";
        if (uri.rfind("data:", 0) == 0) {
          size_t comma = uri.find(',');
          if (comma == std::string::npos ||
              uri.substr(0, comma).find(";base64") == std::string::npos)
            fail("{}: buffer {} has a data: URI that is not base64", name, i);
          owned.push_back(decode_base64(std::string_view(uri).substr(comma + 1), name));
        } else if (resolver) {
          owned.push_back(resolver(uri));
        } else {
          fail("{}: buffer {} refers to external file '{}', which this reader does not fetch", name,
               i, uri);
        }
        data = owned.back();
      }
      if (data.size() < length)
        fail("{}: buffer {} holds {} bytes, byteLength says {}", name, i, data.size(), length);
      buffers.push_back(data.first(length));
    }
  }

  void load_views() {
    const json& list = j.value("bufferViews", json::array());
    if (!list.is_array()) fail("{}: bufferViews is not an array", name);
    for (size_t i = 0; i < list.size(); ++i) {
      const json& v = list[i];
      uint32_t stride =
          uint32_t(std::min<uint64_t>(uint_of(v, "byteStride", 0, name, "bufferView"), 1u << 20));
      auto ext = v.find("extensions");
      if (ext != v.end() && ext->contains("EXT_meshopt_compression")) {
        views.push_back(decode_meshopt((*ext)["EXT_meshopt_compression"], i));
        view_strides.push_back(stride);
        continue;
      }
      size_t b = index_of(v, "buffer", buffers.size(), name, "bufferView");
      uint64_t offset = uint_of(v, "byteOffset", 0, name, "bufferView");
      uint64_t length = uint_of(v, "byteLength", 0, name, "bufferView");
      if (offset > buffers[b].size() || buffers[b].size() - offset < length)
        fail("{}: bufferView {} ({} bytes at {}) lies outside buffer {} ({} bytes)", name, i,
             length, offset, b, buffers[b].size());
      views.push_back(buffers[b].subspan(offset, length));
      view_strides.push_back(stride);
    }
  }

  std::span<const uint8_t> decode_meshopt(const json& e, size_t view) {
    size_t b = index_of(e, "buffer", buffers.size(), name, "EXT_meshopt_compression");
    uint64_t offset = uint_of(e, "byteOffset", 0, name, "EXT_meshopt_compression");
    uint64_t length = uint_of(e, "byteLength", 0, name, "EXT_meshopt_compression");
    uint64_t stride = uint_of(e, "byteStride", 0, name, "EXT_meshopt_compression");
    uint64_t count = uint_of(e, "count", 0, name, "EXT_meshopt_compression");
    std::string mode = e.value("mode", "");
    std::string filter = e.value("filter", "NONE");
    if (offset > buffers[b].size() || buffers[b].size() - offset < length)
      fail("{}: compressed bufferView {} lies outside buffer {}", name, view, b);
    if (stride == 0 || stride > 256 || count > limits.max_points * 4)
      fail("{}: compressed bufferView {} has invalid byteStride {} or count {}", name, view, stride,
           count);
    const uint8_t* src = buffers[b].data() + offset;
    owned.emplace_back(size_t(count * stride));
    auto& out = owned.back();
    int rc = 0;
    if (mode == "ATTRIBUTES") {
      if (stride % 4 != 0)
        fail("{}: meshopt ATTRIBUTES stride {} is not a multiple of 4", name, stride);
      rc = meshopt_decodeVertexBuffer(out.data(), count, stride, src, length);
      if (rc == 0) {
        if (filter == "OCTAHEDRAL") {
          if (stride != 4 && stride != 8) fail("{}: OCTAHEDRAL filter needs stride 4 or 8", name);
          meshopt_decodeFilterOct(out.data(), count, stride);
        } else if (filter == "QUATERNION") {
          if (stride != 8) fail("{}: QUATERNION filter needs stride 8", name);
          meshopt_decodeFilterQuat(out.data(), count, stride);
        } else if (filter == "EXPONENTIAL") {
          meshopt_decodeFilterExp(out.data(), count, stride);
        } else if (filter != "NONE") {
          fail("{}: unknown meshopt filter {}", name, filter);
        }
      }
    } else if (mode == "TRIANGLES" || mode == "INDICES") {
      if (stride != 2 && stride != 4)
        fail("{}: meshopt index stride {} is not 2 or 4", name, stride);
      if (mode == "TRIANGLES" && count % 3 != 0)
        fail("{}: meshopt TRIANGLES count is not a multiple of 3", name);
      rc = mode == "TRIANGLES"
               ? meshopt_decodeIndexBuffer(out.data(), count, stride, src, length)
               : meshopt_decodeIndexSequence(out.data(), count, stride, src, length);
    } else {
      fail("{}: unknown meshopt mode '{}'", name, mode);
    }
    if (rc != 0) fail("{}: meshopt data of bufferView {} cannot be decoded ({})", name, view, rc);
    return out;
  }

  // Reads accessor `index` as doubles (normalized integers mapped to [0,1] / [-1,1]).
  std::vector<double> accessor(size_t index, int& components) {
    const json& list = j["accessors"];
    const json& a = list[index];
    int type_size = 0;
    uint64_t ct = uint_of(a, "componentType", 0, name, "accessor");
    switch (ct) {
      case 5120:
      case 5121:
        type_size = 1;
        break;
      case 5122:
      case 5123:
        type_size = 2;
        break;
      case 5125:
      case 5126:
        type_size = 4;
        break;
      default:
        fail("{}: accessor {} has unknown componentType {}", name, index, ct);
    }
    std::string type = a.value("type", "");
    components = detail::type_components(type);
    if (components == 0) fail("{}: accessor {} has unsupported type '{}'", name, index, type);
    if (a.contains("sparse"))
      fail("{}: accessor {} is sparse, which is not supported", name, index);
    bool normalized = a.value("normalized", false);
    uint64_t count = uint_of(a, "count", 0, name, "accessor");
    if (count > limits.max_points)
      fail("{}: accessor {} count {} exceeds the limit", name, index, count);
    std::vector<double> out(count * components, 0.0);
    if (!a.contains("bufferView")) return out;  // all zeros by the specification
    size_t v = index_of(a, "bufferView", views.size(), name, "accessor");
    uint64_t offset = uint_of(a, "byteOffset", 0, name, "accessor");
    uint64_t elem = uint64_t(type_size) * components;
    uint64_t stride = view_strides[v] ? view_strides[v] : elem;
    if (stride < elem)
      fail("{}: accessor {} stride {} is smaller than its element", name, index, stride);
    if (count > 0 && (offset > views[v].size() || (views[v].size() - offset < elem) ||
                      (views[v].size() - offset - elem) / stride < count - 1))
      fail("{}: accessor {} ({} elements, stride {}, offset {}) runs past bufferView {} ({} bytes)",
           name, index, count, stride, offset, v, views[v].size());
    const uint8_t* base = views[v].data() + offset;
    for (uint64_t i = 0; i < count; ++i) {
      const uint8_t* p = base + i * stride;
      for (int k = 0; k < components; ++k) {
        const uint8_t* q = p + k * type_size;
        double x = 0;
        switch (ct) {
          case 5120: {
            int8_t t;
            std::memcpy(&t, q, 1);
            x = normalized ? std::max(t / 127.0, -1.0) : t;
            break;
          }
          case 5121: {
            uint8_t t = *q;
            x = normalized ? t / 255.0 : t;
            break;
          }
          case 5122: {
            int16_t t;
            std::memcpy(&t, q, 2);
            x = normalized ? std::max(t / 32767.0, -1.0) : t;
            break;
          }
          case 5123: {
            uint16_t t;
            std::memcpy(&t, q, 2);
            x = normalized ? t / 65535.0 : t;
            break;
          }
          case 5125: {
            uint32_t t;
            std::memcpy(&t, q, 4);
            x = t;
            break;
          }
          default: {
            float t;
            std::memcpy(&t, q, 4);
            x = t;
            break;
          }
        }
        out[i * components + k] = x;
      }
    }
    return out;
  }
};

}  // namespace

// JSON accessors throw nlohmann exceptions on a wrong type; the public entry point below turns
// them into stipple::Error naming the file.
static PointContent decode_glb_points_unchecked(std::span<const uint8_t> data,
                                                const std::string& name, const DecodeLimits& limits,
                                                const BufferResolver& resolver) {
  Gltf g;
  g.name = name;
  g.limits = limits;
  std::span<const uint8_t> bin;
  if (data.size() >= 4 && std::memcmp(data.data(), "glTF", 4) == 0) {
    if (data.size() < 20) fail("{}: too short for a GLB header", name);
    uint32_t version = read_u32(data, 4), length = read_u32(data, 8);
    if (version != 2) fail("{}: GLB version {} is not supported", name, version);
    if (length != data.size())
      fail("{}: GLB length {} does not match the {} bytes received (truncated?)", name, length,
           data.size());
    size_t at = 12;
    std::span<const uint8_t> json_chunk;
    while (at + 8 <= data.size()) {
      uint32_t chunk_length = read_u32(data, at), type = read_u32(data, at + 4);
      at += 8;
      if (chunk_length > data.size() - at)
        fail("{}: GLB chunk of {} bytes runs past the end", name, chunk_length);
      auto chunk = data.subspan(at, chunk_length);
      if (type == kChunkJson && json_chunk.empty())
        json_chunk = chunk;
      else if (type == kChunkBin && bin.empty())
        bin = chunk;
      at += chunk_length;
    }
    if (json_chunk.empty()) fail("{}: GLB has no JSON chunk", name);
    if (json_chunk.size() > limits.max_json_bytes) fail("{}: GLB JSON too large", name);
    g.j = json::parse(json_chunk.begin(), json_chunk.end(), nullptr, false);
  } else {
    g.j = json::parse(data.begin(), data.end(), nullptr, false);
  }
  if (g.j.is_discarded() || !g.j.is_object()) fail("{}: glTF JSON is not valid", name);
  json& j = g.j;

  PointContent c;
  c.format = "glb";
  static const std::set<std::string> supported = {
      "KHR_mesh_quantization", "EXT_meshopt_compression", "CESIUM_RTC", "EXT_structural_metadata"};
  if (auto req = j.find("extensionsRequired"); req != j.end() && req->is_array())
    for (const auto& e : *req)
      if (!e.is_string() || !supported.count(e.get<std::string>()))
        fail("{}: requires glTF extension {}, which is not supported", name, e.dump());
  if (auto used = j.find("extensionsUsed"); used != j.end() && used->is_array())
    for (const auto& e : *used)
      if (e.is_string() && !supported.count(e.get<std::string>()))
        c.warnings.push_back(fmt::format("glTF extension {} ignored", e.get<std::string>()));
  for (const char* key : {"accessors", "meshes", "nodes"})
    if (j.contains(key) && !j[key].is_array()) fail("{}: {} is not an array", name, key);

  g.load_buffers(bin, resolver);
  g.load_views();

  glm::dvec3 rtc(0.0);
  if (auto e = j.find("extensions"); e != j.end() && e->is_object() && e->contains("CESIUM_RTC")) {
    const json& center = (*e)["CESIUM_RTC"]["center"];
    if (!center.is_array() || center.size() != 3 || !center[0].is_number() ||
        !center[1].is_number() || !center[2].is_number())
      fail("{}: CESIUM_RTC center is not three numbers", name);
    rtc = {center[0].get<double>(), center[1].get<double>(), center[2].get<double>()};
  }

  // EXT_structural_metadata property attributes: named, typed views of vertex attributes (with
  // the class's or the property's offset and scale). They are exposed under the property name.
  struct MetaProperty {
    std::string name, attribute;
    double offset = 0, scale = 1;
  };
  std::vector<std::vector<MetaProperty>> property_attributes;
  if (auto e = j.find("extensions"); e != j.end() && e->is_object()) {
    if (auto m = e->find("EXT_structural_metadata"); m != e->end()) {
      if (!m->is_object()) fail("{}: EXT_structural_metadata is not an object", name);
      const json schema = m->value("schema", json::object());
      const json classes = schema.value("classes", json::object());
      auto number_or = [](const json& o, const char* key, double fallback) {
        auto it = o.find(key);
        return it != o.end() && it->is_number() ? it->get<double>() : fallback;
      };
      for (const auto& pa : m->value("propertyAttributes", json::array())) {
        if (!pa.is_object()) fail("{}: a property attribute is not an object", name);
        const std::string cls = pa.value("class", std::string());
        const json class_props =
            classes.is_object() && classes.contains(cls) && classes[cls].is_object()
                ? classes[cls].value("properties", json::object())
                : json::object();
        std::vector<MetaProperty> props;
        const json properties = pa.value("properties", json::object());
        for (const auto& [pname, p] : properties.items()) {
          if (!p.is_object() || !p.contains("attribute") || !p["attribute"].is_string())
            fail("{}: property attribute property '{}' names no attribute", name, pname);
          MetaProperty mp{pname, p["attribute"].get<std::string>()};
          if (class_props.is_object() && class_props.contains(pname) &&
              class_props[pname].is_object()) {
            mp.offset = number_or(class_props[pname], "offset", 0.0);
            mp.scale = number_or(class_props[pname], "scale", 1.0);
          }
          mp.offset = number_or(p, "offset", mp.offset);
          mp.scale = number_or(p, "scale", mp.scale);
          props.push_back(std::move(mp));
        }
        property_attributes.push_back(std::move(props));
      }
    }
  }

  const json meshes = j.value("meshes", json::array());
  const json materials = j.value("materials", json::array());
  const size_t accessor_count = j.value("accessors", json::array()).size();

  std::vector<glm::dvec3> points;
  std::vector<uint32_t> rgba;
  std::vector<glm::vec3> normals;
  std::vector<uint32_t> batch;
  bool any_color = false, any_normal = false, any_batch = false;
  std::map<std::string, size_t> skipped;  // primitives that are not points, by mode
  const glm::dmat4 y_up_to_z_up(1, 0, 0, 0, 0, 0, 1, 0, 0, -1, 0, 0, 0, 0, 0, 1);

  for (const gltf_nodes::MeshNode& mn : gltf_nodes::mesh_nodes(j, name)) {
    const glm::dmat4& m = mn.world;
    const json& mesh = meshes[mn.mesh];
    glm::dmat4 to_tile = y_up_to_z_up * m;
    glm::dmat3 normal_matrix = glm::transpose(glm::inverse(glm::dmat3(to_tile)));
    for (const auto& prim : mesh.value("primitives", json::array())) {
      if (const int64_t mode = prim.value("mode", int64_t(4)); mode != 0) {
        static constexpr const char* kModes[] = {"POINTS",      "LINES",     "LINE_LOOP",
                                                 "LINE_STRIP",  "TRIANGLES", "TRIANGLE_STRIP",
                                                 "TRIANGLE_FAN"};
        ++skipped[mode > 0 && mode < 7 ? kModes[mode] : fmt::format("mode {}", mode)];
        continue;
      }
      const json& attrs = prim.value("attributes", json::object());
      if (!attrs.is_object() || !attrs.contains("POSITION"))
        fail("{}: a point primitive has no POSITION", name);
      int comps = 0;
      auto pos = g.accessor(index_of(attrs, "POSITION", accessor_count, name, "primitive"), comps);
      if (comps != 3) fail("{}: POSITION is not VEC3", name);
      size_t n = pos.size() / 3, first = points.size();
      if (first + n > limits.max_points) fail("{}: more than {} points", name, limits.max_points);
      for (size_t i = 0; i < n; ++i) {
        glm::dvec4 p = to_tile * glm::dvec4(pos[i * 3], pos[i * 3 + 1], pos[i * 3 + 2], 1.0);
        points.push_back(glm::dvec3(p) + rtc);
      }
      auto per_point = [&](const char* key, auto& out, auto convert, bool& any) {
        if (!attrs.contains(key)) return false;
        int k = 0;
        auto v = g.accessor(index_of(attrs, key, accessor_count, name, "primitive"), k);
        if (v.size() / std::max(k, 1) != n) fail("{}: {} count differs from POSITION", name, key);
        out.resize(first);
        for (size_t i = 0; i < n; ++i) out.push_back(convert(&v[i * k], k));
        any = true;
        return true;
      };
      auto to_byte = [](double x) {
        return uint32_t(std::lround(std::clamp(x, 0.0, 1.0) * 255.0));
      };
      // glTF's COLOR_0 is linear; stipple's colours are sRGB-encoded (as LAS and pnts RGB), so
      // RGB goes through the sRGB transfer function. Alpha is linear in both.
      auto to_srgb = [](double x) { return uint32_t(color::linear_to_srgb8(x)); };
      per_point(
          "COLOR_0", rgba,
          [&](const double* v, int k) {
            if (k != 3 && k != 4) fail("{}: COLOR_0 is not VEC3 or VEC4", name);
            return to_srgb(v[0]) | (to_srgb(v[1]) << 8) | (to_srgb(v[2]) << 16) |
                   ((k == 4 ? to_byte(v[3]) : 255u) << 24);
          },
          any_color);
      // Alpha counts only where the material blends or masks (glTF: OPAQUE ignores it). MASK is
      // applied here at its cutoff (0 or 255); BLEND keeps it for blending (PointContent::alpha).
      if (any_color && rgba.size() == first + n) {
        std::string mode = "OPAQUE";
        double cutoff = 0.5;
        if (prim.contains("material") && prim["material"].is_number_unsigned() &&
            prim["material"].get<uint64_t>() < materials.size() &&
            materials[prim["material"].get<size_t>()].is_object()) {
          const json& m = materials[prim["material"].get<size_t>()];
          if (m.contains("alphaMode") && m["alphaMode"].is_string()) mode = m["alphaMode"];
          if (m.contains("alphaCutoff") && m["alphaCutoff"].is_number())
            cutoff = m["alphaCutoff"].get<double>();
        }
        const uint32_t cut = uint32_t(std::clamp(cutoff, 0.0, 1.0) * 255.0 + 0.5);
        for (size_t i = first; i < first + n; ++i) {
          const uint32_t a = rgba[i] >> 24;
          const uint32_t kept = mode == "BLEND"  ? a
                                : mode == "MASK" ? (a >= cut ? 255u : 0u)
                                                 : 255u;
          rgba[i] = (rgba[i] & 0x00ffffffu) | (kept << 24);
        }
        c.alpha = c.alpha || mode == "BLEND" || mode == "MASK";
      }
      per_point(
          "NORMAL", normals,
          [&](const double* v, int k) {
            if (k != 3) fail("{}: NORMAL is not VEC3", name);
            glm::dvec3 nrm = normal_matrix * glm::dvec3(v[0], v[1], v[2]);
            double len = glm::length(nrm);
            return glm::vec3(len > 0 ? nrm / len : nrm);
          },
          any_normal);
      const char* id_key = attrs.contains("_FEATURE_ID_0") ? "_FEATURE_ID_0" : "_BATCHID";
      per_point(
          id_key, batch,
          [&](const double* v, int) {
            if (v[0] < 0 || v[0] > 4294967295.0) fail("{}: {} out of range", name, id_key);
            return uint32_t(v[0]);
          },
          any_batch);
      for (const auto& [key, index] : attrs.items()) {
        if (key == "POSITION" || key == "COLOR_0" || key == "NORMAL" || key == id_key) continue;
        int k = 0;
        auto v = g.accessor(index_of(attrs, key.c_str(), accessor_count, name, "primitive"), k);
        if (v.size() / k != n) fail("{}: {} count differs from POSITION", name, key);
        auto& attr = c.attributes[key];
        if (attr.values.empty()) attr.components = k;
        if (attr.components != k)
          fail("{}: attribute {} changes type between primitives", name, key);
        attr.component_type = "glTF";
        attr.values.resize(first * k);
        attr.values.insert(attr.values.end(), v.begin(), v.end());
      }
      const json prim_ext = prim.value("extensions", json::object());
      if (prim_ext.is_object() && prim_ext.contains("EXT_structural_metadata")) {
        const json& sm = prim_ext["EXT_structural_metadata"];
        for (const auto& idx : sm.value("propertyAttributes", json::array())) {
          if (!idx.is_number_unsigned() || idx.get<uint64_t>() >= property_attributes.size())
            fail("{}: a primitive names a property attribute that does not exist", name);
          for (const MetaProperty& mp : property_attributes[idx.get<size_t>()]) {
            if (mp.name == mp.attribute || attrs.contains(mp.name)) continue;
            auto src = c.attributes.find(mp.attribute);
            if (!attrs.contains(mp.attribute) || src == c.attributes.end())
              fail("{}: property '{}' names attribute {}, which the primitive lacks", name, mp.name,
                   mp.attribute);
            const int k = src->second.components;
            auto& dst = c.attributes[mp.name];
            if (dst.values.empty()) dst.components = k;
            if (dst.components != k)
              fail("{}: property {} changes type between primitives", name, mp.name);
            dst.component_type = "metadata";
            dst.values.resize(first * k);
            for (size_t i = first * k; i < (first + n) * k; ++i)
              dst.values.push_back(src->second.values[i] * mp.scale + mp.offset);
          }
        }
      }
    }
  }
  if (!skipped.empty() && points.empty()) {
    c.not_drawn = "glb meshes";  // said once per kind by the streamer, and by info
  } else if (!skipped.empty()) {
    std::string list;
    for (const auto& [mode, count] : skipped)
      list += fmt::format("{}{} {} primitive{}", list.empty() ? "" : ", ", count, mode,
                          count > 1 ? "s" : "");
    c.warnings.push_back(fmt::format("{} skipped (only points are drawn)", list));
  }
  c.point_count = points.size();
  if (any_color) rgba.resize(points.size(), 0xffffffffu);
  if (any_normal) normals.resize(points.size(), glm::vec3(0, 0, 1));
  if (any_batch) batch.resize(points.size(), 0);
  for (auto& [key, attr] : c.attributes) attr.values.resize(points.size() * attr.components);
  // Floats relative to the middle of the points keep precision for ECEF-sized coordinates.
  glm::dvec3 lo(INFINITY), hi(-INFINITY);
  for (const auto& p : points) {
    if (!std::isfinite(p.x) || !std::isfinite(p.y) || !std::isfinite(p.z))
      fail("{}: a position is not finite", name);
    lo = glm::min(lo, p);
    hi = glm::max(hi, p);
  }
  c.center = points.empty() ? rtc : (lo + hi) * 0.5;
  c.positions.reserve(points.size());
  for (const auto& p : points) c.positions.push_back(glm::vec3(p - c.center));
  c.rgba = std::move(rgba);
  c.normals = std::move(normals);
  c.batch_ids = std::move(batch);
  if (!c.batch_ids.empty())
    c.batch_length = *std::max_element(c.batch_ids.begin(), c.batch_ids.end()) + 1;
  c.warnings.insert(c.warnings.end(), g.warnings.begin(), g.warnings.end());
  return c;
}

PointContent decode_glb_points(std::span<const uint8_t> data, const std::string& name,
                               const DecodeLimits& limits, const BufferResolver& resolver) {
  try {
    return decode_glb_points_unchecked(data, name, limits, resolver);
  } catch (const nlohmann::json::exception& e) {
    fail("{}: malformed JSON: {}", name, e.what());
  }
}

}  // namespace stipple::io
