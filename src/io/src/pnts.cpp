#include "stipple/io/pnts.hpp"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <set>

#include <draco/compression/decode.h>
#include <nlohmann/json.hpp>

#include "stipple/core/error.hpp"

namespace stipple::io {

using json = nlohmann::json;

uint64_t PointContent::memory_bytes() const {
  uint64_t bytes = sizeof(*this) + positions.size() * sizeof(glm::vec3) +
                   rgba.size() * sizeof(uint32_t) + normals.size() * sizeof(glm::vec3) +
                   batch_ids.size() * sizeof(uint32_t);
  for (const auto& [name, a] : attributes) bytes += name.size() + a.values.size() * sizeof(double);
  if (splats)
    bytes += sizeof(SplatSet) +
             splats->size() * (2 * sizeof(glm::vec3) + sizeof(glm::vec4) + sizeof(float) +
                               sizeof(glm::vec3) * (1 + splats->rest_count()));
  return bytes;
}

namespace detail {

uint32_t read_u32(std::span<const uint8_t> data, size_t offset) {
  if (offset > data.size() || data.size() - offset < 4) fail("read past the end of the data");
  uint32_t v;
  std::memcpy(&v, data.data() + offset, 4);
  return v;
}

uint64_t read_u64(std::span<const uint8_t> data, size_t offset) {
  if (offset > data.size() || data.size() - offset < 8) fail("read past the end of the data");
  uint64_t v;
  std::memcpy(&v, data.data() + offset, 8);
  return v;
}

int component_size(const std::string& type) {
  if (type == "BYTE" || type == "UNSIGNED_BYTE") return 1;
  if (type == "SHORT" || type == "UNSIGNED_SHORT") return 2;
  if (type == "INT" || type == "UNSIGNED_INT" || type == "FLOAT") return 4;
  if (type == "DOUBLE") return 8;
  return 0;
}

double read_component(const uint8_t* p, const std::string& type) {
  auto get = [p](auto v) {
    std::memcpy(&v, p, sizeof(v));
    return double(v);
  };
  if (type == "BYTE") return get(int8_t());
  if (type == "UNSIGNED_BYTE") return get(uint8_t());
  if (type == "SHORT") return get(int16_t());
  if (type == "UNSIGNED_SHORT") return get(uint16_t());
  if (type == "INT") return get(int32_t());
  if (type == "UNSIGNED_INT") return get(uint32_t());
  if (type == "FLOAT") return get(float());
  return get(double());
}

int type_components(const std::string& type) {
  if (type == "SCALAR") return 1;
  if (type == "VEC2") return 2;
  if (type == "VEC3") return 3;
  if (type == "VEC4") return 4;
  return 0;
}

}  // namespace detail

namespace {

using namespace detail;

json parse_json_chunk(std::span<const uint8_t> bytes, const std::string& name, const char* what) {
  if (bytes.empty()) return json::object();
  size_t n = bytes.size();
  while (n > 0 && (bytes[n - 1] == 0 || bytes[n - 1] == ' ')) --n;  // padding
  json j = json::parse(bytes.begin(), bytes.begin() + std::ptrdiff_t(n), nullptr, false);
  if (j.is_discarded()) fail("{}: the {} is not valid JSON", name, what);
  if (!j.is_object()) fail("{}: the {} is not a JSON object", name, what);
  return j;
}

// A table (feature or batch) with its binary body: resolves {"byteOffset": n} references.
struct Table {
  const json& j;
  std::span<const uint8_t> body;
  const std::string& name;
  const char* what;

  uint64_t offset_of(const json& ref, const std::string& key) const {
    const auto it = ref.find("byteOffset");
    if (it == ref.end() || !it->is_number_integer() || it->get<int64_t>() < 0)
      fail("{}: {} property {} has no valid byteOffset", name, what, key);
    return it->get<uint64_t>();
  }
  // The bytes of `count` elements of `elem` bytes at the property's byteOffset, checked.
  const uint8_t* bytes(const json& ref, const std::string& key, uint64_t elem,
                       uint64_t count) const {
    uint64_t offset = offset_of(ref, key);
    if (offset > body.size() || (body.size() - offset) / elem < count)
      fail(
          "{}: {} property {} ({} x {} bytes at offset {}) runs past the end of the binary body "
          "({} bytes)",
          name, what, key, count, elem, offset, body.size());
    return body.data() + offset;
  }
  // A global semantic: a JSON number/array, or a binary reference of `n` components.
  std::vector<double> global(const std::string& key, size_t n, const std::string& type) const {
    auto it = j.find(key);
    if (it == j.end()) return {};
    std::vector<double> out;
    if (it->is_number()) {
      out.push_back(it->get<double>());
    } else if (it->is_array()) {
      for (const auto& v : *it) {
        if (!v.is_number()) fail("{}: {} {} holds a non-number", name, what, key);
        out.push_back(v.get<double>());
      }
    } else if (it->is_object()) {
      std::string ct = it->value("componentType", type);
      int size = component_size(ct);
      if (size == 0) fail("{}: {} {} has unknown componentType {}", name, what, key, ct);
      const uint8_t* p = bytes(*it, key, uint64_t(size), n);
      for (size_t i = 0; i < n; ++i) out.push_back(read_component(p + i * size, ct));
    } else {
      fail("{}: {} {} has an unexpected JSON type", name, what, key);
    }
    if (out.size() != n)
      fail("{}: {} {} has {} values, expected {}", name, what, key, out.size(), n);
    for (double v : out)
      if (!std::isfinite(v)) fail("{}: {} {} is not finite", name, what, key);
    return out;
  }
};

uint32_t rgb565_to_rgba(uint16_t v) {
  uint32_t r = (v >> 11) & 31, g = (v >> 5) & 63, b = v & 31;
  r = (r * 255 + 15) / 31;
  g = (g * 255 + 31) / 63;
  b = (b * 255 + 15) / 31;
  return r | (g << 8) | (b << 16) | (255u << 24);
}

glm::vec3 oct_decode(float x, float y) {  // x, y in [-1, 1]
  glm::vec3 v(x, y, 1.0f - std::abs(x) - std::abs(y));
  if (v.z < 0) {
    float ox = v.x;
    v.x = (1.0f - std::abs(v.y)) * (ox >= 0 ? 1.0f : -1.0f);
    v.y = (1.0f - std::abs(ox)) * (v.y >= 0 ? 1.0f : -1.0f);
  }
  float len = std::sqrt(v.x * v.x + v.y * v.y + v.z * v.z);
  return len > 0 ? v / len : glm::vec3(0, 0, 1);
}

// The Draco point cloud of 3DTILES_draco_point_compression, decoded once for both tables.
struct DracoCloud {
  std::unique_ptr<draco::PointCloud> cloud;
  const draco::PointAttribute* attribute(const json& properties, const std::string& key,
                                         const std::string& name) const {
    auto it = properties.find(key);
    if (it == properties.end()) return nullptr;
    if (!it->is_number_integer()) fail("{}: Draco property {} is not an attribute id", name, key);
    const draco::PointAttribute* a = cloud->GetAttributeByUniqueId(it->get<uint32_t>());
    if (!a) fail("{}: Draco attribute id {} ({}) is not in the Draco data", name, *it, key);
    return a;
  }
};

template <typename T>
std::vector<T> draco_values(const draco::PointAttribute* a, size_t count, int components,
                            const std::string& name, const std::string& key) {
  if (a->num_components() < components)
    fail("{}: Draco attribute {} has {} components, expected {}", name, key,
         int(a->num_components()), components);
  // 3D Tiles maps every attribute to a numeric Draco type; Draco's own conversion from DT_BOOL
  // loads raw bytes as bool, which is undefined for anything but 0 and 1.
  if (a->data_type() == draco::DT_BOOL || a->data_type() == draco::DT_INVALID ||
      a->data_type() >= draco::DT_TYPES_COUNT)
    fail("{}: Draco attribute {} has a non-numeric data type", name, key);
  std::vector<T> out(count * size_t(components));
  for (size_t i = 0; i < count; ++i) {
    auto index = a->mapped_index(draco::PointIndex(uint32_t(i)));
    if (index.value() >= a->size() ||
        !a->ConvertValue<T>(index, int8_t(components), out.data() + i * components))
      fail("{}: Draco attribute {} cannot be read", name, key);
  }
  return out;
}

void decode_batch_table(PointContent& c, const json& bt, std::span<const uint8_t> body,
                        const DracoCloud* draco, const std::string& name) {
  Table table{bt, body, name, "batch table"};
  const size_t count = c.batch_ids.empty() ? c.point_count : c.batch_length;
  const json* draco_props = nullptr;
  if (auto ext = bt.find("extensions"); ext != bt.end() && ext->is_object()) {
    for (const auto& [key, value] : ext->items()) {
      if (key == "3DTILES_draco_point_compression") {
        draco_props = value.contains("properties") ? &value["properties"] : nullptr;
      } else {
        c.warnings.push_back(fmt::format("batch table extension {} ignored", key));
      }
    }
  }
  // extras.offsets: a number added to a property's values (stipple's tiler stores GPS time as
  // float seconds after the tile's earliest time; glTF metadata has the same offset).
  const json no_offsets = json::object();
  const json* offsets = &no_offsets;
  if (auto ex = bt.find("extras"); ex != bt.end() && ex->is_object())
    if (auto o = ex->find("offsets"); o != ex->end() && o->is_object()) offsets = &*o;
  for (const auto& [key, value] : bt.items()) {
    if (key == "extensions" || key == "extras") continue;
    PointAttribute attr;
    if (value.is_array()) {
      attr.component_type = "JSON";
      if (value.size() != count)
        fail("{}: batch table property {} has {} values, expected {}", name, key, value.size(),
             count);
      bool numeric = true;
      for (const auto& v : value) {
        if (v.is_number()) {
          attr.values.push_back(v.get<double>());
        } else if (v.is_boolean()) {
          attr.values.push_back(v.get<bool>() ? 1.0 : 0.0);
        } else {
          numeric = false;
          break;
        }
      }
      if (!numeric) {
        c.warnings.push_back(fmt::format("batch table property {} is not numeric; skipped", key));
        continue;
      }
    } else if (value.is_object()) {
      attr.component_type = value.value("componentType", "");
      std::string type = value.value("type", "");
      int size = component_size(attr.component_type);
      attr.components = type_components(type);
      if (size == 0 || attr.components == 0)
        fail(
            "{}: batch table property {} has componentType '{}' / type '{}' that are not "
            "known",
            name, key, attr.component_type, type);
      const draco::PointAttribute* da =
          draco && draco_props ? draco->attribute(*draco_props, key, name) : nullptr;
      if (da) {
        attr.values = draco_values<double>(da, c.point_count, attr.components, name, key);
        if (auto o = offsets->find(key); o != offsets->end() && o->is_number())
          for (double& v : attr.values) v += o->get<double>();
        c.attributes[key] = std::move(attr);
        continue;  // Draco attributes are per point already
      }
      const uint8_t* p = table.bytes(value, key, uint64_t(size) * attr.components, count);
      attr.values.resize(count * attr.components);
      for (size_t i = 0; i < attr.values.size(); ++i)
        attr.values[i] = read_component(p + i * size, attr.component_type);
    } else {
      fail("{}: batch table property {} is neither an array nor a binary reference", name, key);
    }
    if (auto o = offsets->find(key); o != offsets->end() && o->is_number())
      for (double& v : attr.values) v += o->get<double>();
    // Per batch values become per point values through BATCH_ID.
    if (!c.batch_ids.empty()) {
      std::vector<double> per_point(c.point_count * attr.components);
      for (size_t i = 0; i < c.point_count; ++i)
        for (int k = 0; k < attr.components; ++k)
          per_point[i * attr.components + k] = attr.values[c.batch_ids[i] * attr.components + k];
      attr.values = std::move(per_point);
    }
    c.attributes[key] = std::move(attr);
  }
}

}  // namespace

// JSON accessors throw nlohmann exceptions on a wrong type; the public entry point below turns
// them into stipple::Error naming the file.
static PointContent decode_pnts_unchecked(std::span<const uint8_t> data, const std::string& name,
                                          const DecodeLimits& limits) {
  if (data.size() < 28) fail("{}: {} bytes is too short for a pnts header", name, data.size());
  if (std::memcmp(data.data(), "pnts", 4) != 0) fail("{}: not a pnts file (bad magic)", name);
  uint32_t version = read_u32(data, 4);
  if (version != 1) fail("{}: pnts version {} is not supported", name, version);
  uint64_t byte_length = read_u32(data, 8);
  uint64_t ft_json = read_u32(data, 12), ft_bin = read_u32(data, 16);
  uint64_t bt_json = read_u32(data, 20), bt_bin = read_u32(data, 24);
  if (byte_length != data.size())
    fail("{}: header byteLength {} does not match the {} bytes received (truncated?)", name,
         byte_length, data.size());
  if (28 + ft_json + ft_bin + bt_json + bt_bin > data.size())
    fail("{}: table lengths ({} + {} + {} + {}) exceed the tile's {} bytes", name, ft_json, ft_bin,
         bt_json, bt_bin, data.size());
  if (ft_json > limits.max_json_bytes || bt_json > limits.max_json_bytes)
    fail("{}: JSON header larger than {} bytes", name, limits.max_json_bytes);
  size_t at = 28;
  json ft = parse_json_chunk(data.subspan(at, ft_json), name, "feature table");
  at += ft_json;
  auto ft_body = data.subspan(at, ft_bin);
  at += ft_bin;
  json bt = parse_json_chunk(data.subspan(at, bt_json), name, "batch table");
  at += bt_json;
  auto bt_body = data.subspan(at, bt_bin);

  PointContent c;
  c.format = "pnts";
  Table table{ft, ft_body, name, "feature table"};
  auto points = table.global("POINTS_LENGTH", 1, "UNSIGNED_INT");
  if (points.empty()) fail("{}: feature table has no POINTS_LENGTH", name);
  if (points[0] < 0 || points[0] != std::floor(points[0]) || points[0] > double(limits.max_points))
    fail("{}: POINTS_LENGTH {} is not a valid point count (limit {})", name, points[0],
         limits.max_points);
  const size_t n = size_t(points[0]);
  c.point_count = n;
  if (n == 0) return c;  // an empty tile: nothing to decode (and no zero-length copies)
  if (auto rtc = table.global("RTC_CENTER", 3, "FLOAT"); !rtc.empty())
    c.center = {rtc[0], rtc[1], rtc[2]};

  static const std::set<std::string> known = {"POINTS_LENGTH",
                                              "RTC_CENTER",
                                              "QUANTIZED_VOLUME_OFFSET",
                                              "QUANTIZED_VOLUME_SCALE",
                                              "CONSTANT_RGBA",
                                              "BATCH_LENGTH",
                                              "POSITION",
                                              "POSITION_QUANTIZED",
                                              "RGBA",
                                              "RGB",
                                              "RGB565",
                                              "NORMAL",
                                              "NORMAL_OCT16P",
                                              "BATCH_ID",
                                              "extensions",
                                              "extras"};
  for (const auto& [key, value] : ft.items())
    if (!known.count(key)) c.warnings.push_back(fmt::format("unknown semantic {} ignored", key));

  // Draco: decode once; the extension's properties map semantics to Draco attribute ids.
  DracoCloud draco;
  const json* draco_props = nullptr;
  if (auto ext = ft.find("extensions"); ext != ft.end() && ext->is_object()) {
    for (const auto& [key, value] : ext->items()) {
      if (key != "3DTILES_draco_point_compression") {
        c.warnings.push_back(fmt::format("feature table extension {} ignored", key));
        continue;
      }
      if (!value.is_object() || !value.contains("properties") || !value["properties"].is_object())
        fail("{}: 3DTILES_draco_point_compression has no properties", name);
      draco_props = &value["properties"];
      const uint8_t* p = table.bytes(value, "3DTILES_draco_point_compression", 1,
                                     value.value("byteLength", uint64_t(0)));
      uint64_t length = value.value("byteLength", uint64_t(0));
      // Draco sizes its allocations from the point count in its own header: check that count
      // against POINTS_LENGTH before decoding (a corrupt count made it ask for gigabytes).
      // Layout: "DRACO", major, minor, encoder type, method, flags (u16), then for point clouds
      // (both sequential and k-d tree methods) the point count as int32; metadata, flagged by
      // bit 15, would come before it.
      if (length < 15 || std::memcmp(p, "DRACO", 5) != 0)
        fail("{}: 3DTILES_draco_point_compression data is not a Draco buffer", name);
      uint16_t draco_flags = uint16_t(p[9] | p[10] << 8);
      if (draco_flags & 0x8000) fail("{}: Draco buffers with metadata are not supported", name);
      int32_t draco_points = 0;
      std::memcpy(&draco_points, p + 11, 4);
      if (draco_points < 0 || uint64_t(draco_points) != n)
        fail("{}: Draco header says {} points, POINTS_LENGTH says {}", name, draco_points, n);
      draco::DecoderBuffer buffer;
      buffer.Init(reinterpret_cast<const char*>(p), size_t(length));
      draco::Decoder decoder;
      auto status = decoder.DecodePointCloudFromBuffer(&buffer);
      if (!status.ok())
        fail("{}: Draco data cannot be decoded: {}", name, status.status().error_msg_string());
      draco.cloud = std::move(status).value();
      if (draco.cloud->num_points() != n)
        fail("{}: Draco data holds {} points, POINTS_LENGTH says {}", name,
             draco.cloud->num_points(), n);
      c.format = "pnts+draco";
    }
  }
  auto from_draco = [&](const char* key) -> const draco::PointAttribute* {
    return draco_props ? draco.attribute(*draco_props, key, name) : nullptr;
  };

  // Positions.
  c.positions.resize(n);
  if (const auto* a = from_draco("POSITION")) {
    auto v = draco_values<float>(a, n, 3, name, "POSITION");
    std::memcpy(c.positions.data(), v.data(), n * sizeof(glm::vec3));
  } else if (auto it = ft.find("POSITION"); it != ft.end()) {
    const uint8_t* p = table.bytes(*it, "POSITION", 12, n);
    std::memcpy(c.positions.data(), p, n * 12);
  } else if (auto q = ft.find("POSITION_QUANTIZED"); q != ft.end()) {
    auto offset = table.global("QUANTIZED_VOLUME_OFFSET", 3, "FLOAT");
    auto scale = table.global("QUANTIZED_VOLUME_SCALE", 3, "FLOAT");
    if (offset.empty() || scale.empty())
      fail("{}: POSITION_QUANTIZED needs QUANTIZED_VOLUME_OFFSET and QUANTIZED_VOLUME_SCALE", name);
    // The offset joins the double centre; the floats keep only the in-volume part.
    c.center += glm::dvec3(offset[0], offset[1], offset[2]);
    const uint8_t* p = table.bytes(*q, "POSITION_QUANTIZED", 6, n);
    for (size_t i = 0; i < n; ++i) {
      uint16_t v[3];
      std::memcpy(v, p + i * 6, 6);
      for (int k = 0; k < 3; ++k) c.positions[i][k] = float(v[k] / 65535.0 * scale[k]);
    }
  } else {
    fail("{}: feature table has neither POSITION nor POSITION_QUANTIZED", name);
  }
  for (const auto& p : c.positions)
    if (!std::isfinite(p.x) || !std::isfinite(p.y) || !std::isfinite(p.z))
      fail("{}: a position is not finite", name);

  // Colours: RGBA, RGB, RGB565, then CONSTANT_RGBA (spec order of precedence).
  if (const auto* a = from_draco("RGBA")) {
    auto v = draco_values<uint8_t>(a, n, 4, name, "RGBA");
    c.rgba.resize(n);
    std::memcpy(c.rgba.data(), v.data(), n * 4);
    c.alpha = true;
  } else if (const auto* a3 = from_draco("RGB")) {
    auto v = draco_values<uint8_t>(a3, n, 3, name, "RGB");
    c.rgba.resize(n);
    for (size_t i = 0; i < n; ++i)
      c.rgba[i] = v[i * 3] | (v[i * 3 + 1] << 8) | (v[i * 3 + 2] << 16) | (255u << 24);
  } else if (auto it = ft.find("RGBA"); it != ft.end()) {
    const uint8_t* p = table.bytes(*it, "RGBA", 4, n);
    c.rgba.resize(n);
    std::memcpy(c.rgba.data(), p, n * 4);
    c.alpha = true;
  } else if (auto rgb = ft.find("RGB"); rgb != ft.end()) {
    const uint8_t* p = table.bytes(*rgb, "RGB", 3, n);
    c.rgba.resize(n);
    for (size_t i = 0; i < n; ++i)
      c.rgba[i] = p[i * 3] | (p[i * 3 + 1] << 8) | (p[i * 3 + 2] << 16) | (255u << 24);
  } else if (auto r565 = ft.find("RGB565"); r565 != ft.end()) {
    const uint8_t* p = table.bytes(*r565, "RGB565", 2, n);
    c.rgba.resize(n);
    for (size_t i = 0; i < n; ++i) {
      uint16_t v;
      std::memcpy(&v, p + i * 2, 2);
      c.rgba[i] = rgb565_to_rgba(v);
    }
  } else if (auto k = table.global("CONSTANT_RGBA", 4, "UNSIGNED_BYTE"); !k.empty()) {
    for (double v : k)
      if (v < 0 || v > 255) fail("{}: CONSTANT_RGBA value {} is not a byte", name, v);
    uint32_t packed =
        uint32_t(k[0]) | (uint32_t(k[1]) << 8) | (uint32_t(k[2]) << 16) | (uint32_t(k[3]) << 24);
    c.rgba.assign(n, packed);
    c.constant_color = true;
    c.alpha = true;
  }

  // Normals.
  if (const auto* a = from_draco("NORMAL")) {
    auto v = draco_values<float>(a, n, 3, name, "NORMAL");
    c.normals.resize(n);
    std::memcpy(c.normals.data(), v.data(), n * sizeof(glm::vec3));
  } else if (auto it = ft.find("NORMAL"); it != ft.end()) {
    const uint8_t* p = table.bytes(*it, "NORMAL", 12, n);
    c.normals.resize(n);
    std::memcpy(c.normals.data(), p, n * 12);
  } else if (auto oct = ft.find("NORMAL_OCT16P"); oct != ft.end()) {
    const uint8_t* p = table.bytes(*oct, "NORMAL_OCT16P", 2, n);
    c.normals.resize(n);
    for (size_t i = 0; i < n; ++i)
      c.normals[i] =
          oct_decode(p[i * 2] / 255.0f * 2.0f - 1.0f, p[i * 2 + 1] / 255.0f * 2.0f - 1.0f);
  }

  // Batch ids.
  if (const auto* a = from_draco("BATCH_ID")) {
    c.batch_ids = draco_values<uint32_t>(a, n, 1, name, "BATCH_ID");
  } else if (auto it = ft.find("BATCH_ID"); it != ft.end()) {
    std::string type = it->value("componentType", "UNSIGNED_SHORT");
    if (type != "UNSIGNED_BYTE" && type != "UNSIGNED_SHORT" && type != "UNSIGNED_INT")
      fail("{}: BATCH_ID componentType {} is not UNSIGNED_BYTE/SHORT/INT", name, type);
    int size = component_size(type);
    const uint8_t* p = table.bytes(*it, "BATCH_ID", uint64_t(size), n);
    c.batch_ids.resize(n);
    for (size_t i = 0; i < n; ++i) c.batch_ids[i] = uint32_t(read_component(p + i * size, type));
  }
  if (!c.batch_ids.empty()) {
    uint32_t max_id = *std::max_element(c.batch_ids.begin(), c.batch_ids.end());
    auto length = table.global("BATCH_LENGTH", 1, "UNSIGNED_INT");
    if (length.empty()) {
      c.warnings.push_back("BATCH_ID without BATCH_LENGTH; length taken from the largest id");
      c.batch_length = max_id + 1;
    } else {
      if (length[0] < 0 || length[0] > double(limits.max_points))
        fail("{}: BATCH_LENGTH {} is not valid", name, length[0]);
      c.batch_length = uint32_t(length[0]);
    }
    if (max_id >= c.batch_length)
      fail("{}: BATCH_ID {} is not below BATCH_LENGTH {}", name, max_id, c.batch_length);
  }
  decode_batch_table(c, bt, bt_body, draco.cloud ? &draco : nullptr, name);
  return c;
}

PointContent decode_pnts(std::span<const uint8_t> data, const std::string& name,
                         const DecodeLimits& limits) {
  try {
    return decode_pnts_unchecked(data, name, limits);
  } catch (const nlohmann::json::exception& e) {
    fail("{}: malformed JSON: {}", name, e.what());
  }
}

}  // namespace stipple::io
