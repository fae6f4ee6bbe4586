#include "stipple/tiler/glb_writer.hpp"

#include <algorithm>
#include <cmath>
#include <cstring>

#include <meshoptimizer.h>
#include <nlohmann/json.hpp>

#include "stipple/math/color.hpp"

namespace stipple::tiler {

Box bounds_of(std::span<const TilePoint> points) {
  Box b;
  for (const TilePoint& p : points) b.add(glm::dvec3(p.x, p.y, p.z));
  return b;
}

namespace {

using nlohmann::json;

constexpr int kUnsignedByte = 5121, kUnsignedShort = 5123, kFloat = 5126;
constexpr int kArrayBuffer = 34962;

struct Builder {
  std::vector<uint8_t> bin;
  json views = json::array(), accessors = json::array();
  struct Stream {
    size_t offset, count, stride;
  };
  std::vector<Stream> streams;  // per view, for compression

  // Appends a bufferView of `count` elements of `elem` bytes each, spaced `stride` bytes apart
  // (stride 0: tightly packed); `fill(i, dst)` writes element i. Returns the view's bytes.
  template <typename Fill>
  int view(size_t count, size_t elem, size_t stride, Fill fill) {
    size_t step = stride ? stride : elem;
    size_t offset = bin.size();
    bin.resize(offset + count * step, 0);
    for (size_t i = 0; i < count; ++i) fill(i, bin.data() + offset + i * step);
    bin.resize((bin.size() + 3) & ~size_t(3), 0);
    json v = {{"buffer", 0},
              {"byteOffset", offset},
              {"byteLength", count * step},
              {"target", kArrayBuffer}};
    if (stride) v["byteStride"] = stride;
    views.push_back(v);
    streams.push_back({offset, count, step});
    return int(views.size() - 1);
  }

  // EXT_meshopt_compression: every view becomes a compressed stream in the glb's buffer (0),
  // decoded into a fallback buffer (1) that has no data of its own.
  void compress_meshopt() {
    std::vector<uint8_t> packed;
    size_t fallback = 0;
    for (size_t i = 0; i < streams.size(); ++i) {
      const Stream& s = streams[i];
      std::vector<uint8_t> out(meshopt_encodeVertexBufferBound(s.count, s.stride));
      out.resize(meshopt_encodeVertexBuffer(out.data(), out.size(), bin.data() + s.offset, s.count,
                                            s.stride));
      const size_t at = packed.size();
      packed.insert(packed.end(), out.begin(), out.end());
      packed.resize((packed.size() + 3) & ~size_t(3), 0);
      json& v = views[i];
      v["buffer"] = 1;
      v["byteOffset"] = fallback;
      v["byteStride"] = s.stride;
      v["extensions"] = {{"EXT_meshopt_compression",
                          {{"buffer", 0},
                           {"byteOffset", at},
                           {"byteLength", out.size()},
                           {"byteStride", s.stride},
                           {"count", s.count},
                           {"mode", "ATTRIBUTES"}}}};
      fallback += (s.count * s.stride + 3) & ~size_t(3);
    }
    bin = std::move(packed);
    fallback_bytes = fallback;
  }
  size_t fallback_bytes = 0;
  int accessor(int view, int component, size_t count, const char* type, bool normalized = false) {
    json a = {{"bufferView", view}, {"componentType", component}, {"count", count}, {"type", type}};
    if (normalized) a["normalized"] = true;
    accessors.push_back(a);
    return int(accessors.size() - 1);
  }
};

// 10 bits a coordinate, spread to every third bit.
uint32_t spread3(uint32_t v) {
  v &= 0x3ff;
  v = (v | (v << 16)) & 0x030000ff;
  v = (v | (v << 8)) & 0x0300f00f;
  v = (v | (v << 4)) & 0x030c30c3;
  v = (v | (v << 2)) & 0x09249249;
  return v;
}

void put_u32(std::vector<uint8_t>& out, uint32_t v) {
  uint8_t b[4];
  std::memcpy(b, &v, 4);
  out.insert(out.end(), b, b + 4);
}

}  // namespace

std::vector<TilePoint> morton_ordered(std::span<const TilePoint> points) {
  const Box box = bounds_of(points);
  const glm::dvec3 scale = 1023.0 / glm::max(box.max - box.min, glm::dvec3(1e-9));
  std::vector<std::pair<uint32_t, uint32_t>> keys(points.size());
  for (size_t i = 0; i < points.size(); ++i) {
    const TilePoint& p = points[i];
    const glm::dvec3 q = (glm::dvec3(p.x, p.y, p.z) - box.min) * scale;
    keys[i] = {spread3(uint32_t(q.x)) | spread3(uint32_t(q.y)) << 1 | spread3(uint32_t(q.z)) << 2,
               uint32_t(i)};
  }
  std::sort(keys.begin(), keys.end());
  std::vector<TilePoint> out(points.size());
  for (size_t i = 0; i < keys.size(); ++i) out[i] = points[keys[i].second];
  return out;
}

std::vector<uint8_t> write_glb(std::span<const TilePoint> input, const ContentOptions& options) {
  const size_t n = input.size();
  const bool meshopt = options.compression == Compression::Meshopt;
  // Compressed: points in acquisition order (GPS time), else in Morton order of their position,
  // so that neighbours in the stream are neighbours along a scan line or in space and the delta
  // coding of meshopt finds small steps (GPS order measured 11% smaller than Morton on autzen).
  std::vector<TilePoint> sorted;
  std::span<const TilePoint> points = input;
  if (meshopt) {
    if (options.gps_time) {
      sorted.assign(input.begin(), input.end());
      std::stable_sort(sorted.begin(), sorted.end(), [](const TilePoint& a, const TilePoint& b) {
        return a.gps_time < b.gps_time;
      });
    } else {
      sorted = morton_ordered(input);
    }
    points = sorted;
  }
  Box box = bounds_of(points);
  glm::dvec3 extent = box.max - box.min;
  Builder b;
  json attributes, node;
  bool quantized = quantization_keeps(std::max({extent.x, extent.y, extent.z}), options.precision);
  std::vector<std::string> extensions, extensions_used;
  if (quantized) {
    // Y-up axes: X = x, Y = z, Z = -y. The quantized cube starts at the Y-up minimum corner.
    glm::dvec3 lo(box.min.x, box.min.z, -box.max.y);
    // Steps of the input precision (no finer: finer steps only add bits that carry nothing,
    // about 2 bits an axis on a 100 m tile of 1 cm data), wider where the extent needs it.
    glm::dvec3 step = glm::max(glm::dvec3(extent.x, extent.z, extent.y) / 65535.0,
                               glm::dvec3(std::max(options.precision, 1e-9)));
    auto q = [](double v, double s) {
      return uint16_t(std::clamp(std::lround(v / s), 0L, 65535L));
    };
    uint16_t qmin[3] = {65535, 65535, 65535}, qmax[3] = {0, 0, 0};
    int v = b.view(n, 6, 8, [&](size_t i, uint8_t* dst) {
      const TilePoint& p = points[i];
      uint16_t c[3] = {q(p.x - lo.x, step.x), q(p.z - lo.y, step.y), q(-p.y - lo.z, step.z)};
      for (int k = 0; k < 3; ++k)
        qmin[k] = std::min(qmin[k], c[k]), qmax[k] = std::max(qmax[k], c[k]);
      std::memcpy(dst, c, 6);
    });
    int a = b.accessor(v, kUnsignedShort, n, "VEC3");
    b.accessors[a]["min"] = {qmin[0], qmin[1], qmin[2]};
    b.accessors[a]["max"] = {qmax[0], qmax[1], qmax[2]};
    attributes["POSITION"] = a;
    node["translation"] = {lo.x, lo.y, lo.z};
    node["scale"] = {step.x, step.y, step.z};
    extensions.push_back("KHR_mesh_quantization");
  } else {
    glm::dvec3 c = (box.min + box.max) * 0.5;
    glm::dvec3 cy(c.x, c.z, -c.y);
    float fmin[3] = {1e30f, 1e30f, 1e30f}, fmax[3] = {-1e30f, -1e30f, -1e30f};
    int v = b.view(n, 12, 0, [&](size_t i, uint8_t* dst) {
      const TilePoint& p = points[i];
      float f[3] = {float(p.x - c.x), float(p.z - c.z), float(-(p.y - c.y))};
      for (int k = 0; k < 3; ++k)
        fmin[k] = std::min(fmin[k], f[k]), fmax[k] = std::max(fmax[k], f[k]);
      std::memcpy(dst, f, 12);
    });
    int a = b.accessor(v, kFloat, n, "VEC3");
    b.accessors[a]["min"] = {fmin[0], fmin[1], fmin[2]};
    b.accessors[a]["max"] = {fmax[0], fmax[1], fmax[2]};
    attributes["POSITION"] = a;
    node["translation"] = {cy.x, cy.y, cy.z};
  }
  if (options.rgb) {
    // glTF's COLOR_0 is linear: the sRGB bytes of LAS go through the transfer function, into
    // 16 bits, which keep every 8-bit sRGB value distinct (8 linear bits merge the dark ones).
    int v = b.view(n, 6, 8, [&](size_t i, uint8_t* d) {
      const uint16_t c[3] = {color::srgb8_to_linear16(points[i].r),
                             color::srgb8_to_linear16(points[i].g),
                             color::srgb8_to_linear16(points[i].b)};
      std::memcpy(d, c, 6);
    });
    attributes["COLOR_0"] = b.accessor(v, kUnsignedShort, n, "VEC3", true);
  }
  int vi = b.view(n, 2, 4, [&](size_t i, uint8_t* d) { std::memcpy(d, &points[i].intensity, 2); });
  attributes["_INTENSITY"] = b.accessor(vi, kUnsignedShort, n, "SCALAR");
  int vc = b.view(n, 1, 4, [&](size_t i, uint8_t* d) { d[0] = points[i].classification; });
  attributes["_CLASSIFICATION"] = b.accessor(vc, kUnsignedByte, n, "SCALAR");
  int vr = b.view(n, 1, 4, [&](size_t i, uint8_t* d) { d[0] = points[i].return_number; });
  attributes["_RETURN_NUMBER"] = b.accessor(vr, kUnsignedByte, n, "SCALAR");
  json primitive = {{"attributes", attributes}, {"mode", 0}};
  // The same attributes described as EXT_structural_metadata property attributes, so that
  // clients (CesiumJS styling and picking) know their names and types.
  json properties = {{"intensity", {{"type", "SCALAR"}, {"componentType", "UINT16"}}},
                     {"classification", {{"type", "SCALAR"}, {"componentType", "UINT8"}}},
                     {"return_number", {{"type", "SCALAR"}, {"componentType", "UINT8"}}}};
  json bound = {{"intensity", {{"attribute", "_INTENSITY"}}},
                {"classification", {{"attribute", "_CLASSIFICATION"}}},
                {"return_number", {{"attribute", "_RETURN_NUMBER"}}}};
  if (options.gps_time && n > 0) {
    double t0 = points[0].gps_time;
    for (const TilePoint& p : points) t0 = std::min(t0, p.gps_time);
    int vg = b.view(n, 4, 0, [&](size_t i, uint8_t* d) {
      float f = float(points[i].gps_time - t0);
      std::memcpy(d, &f, 4);
    });
    attributes["_GPS_TIME"] = b.accessor(vg, kFloat, n, "SCALAR");
    primitive["attributes"] = attributes;
    primitive["extras"] = {{"gpsTimeOffset", t0}};
    // Float32 seconds relative to the tile's earliest time; the offset restores GPS time.
    properties["gps_time"] = {{"type", "SCALAR"}, {"componentType", "FLOAT32"}};
    bound["gps_time"] = {{"attribute", "_GPS_TIME"}, {"offset", t0}};
  }
  primitive["extensions"] = {{"EXT_structural_metadata", {{"propertyAttributes", {0}}}}};
  extensions_used.push_back("EXT_structural_metadata");
  node["mesh"] = 0;
  json gltf = {{"asset", {{"version", "2.0"}, {"generator", "stipple tile"}}},
               {"scene", 0},
               {"scenes", json::array({{{"nodes", {0}}}})},
               {"nodes", json::array({node})},
               {"meshes", json::array({{{"primitives", json::array({primitive})}}})},
               {"accessors", b.accessors},
               {"bufferViews", b.views},
               {"buffers", json::array({{{"byteLength", b.bin.size()}}})}};
  gltf["extensions"] = {
      {"EXT_structural_metadata",
       {{"schema",
         {{"id", "stipple_points"}, {"classes", {{"point", {{"properties", properties}}}}}}},
        {"propertyAttributes", json::array({{{"class", "point"}, {"properties", bound}}})}}}};
  if (meshopt) {
    b.compress_meshopt();
    gltf["bufferViews"] = b.views;
    gltf["buffers"] =
        json::array({{{"byteLength", b.bin.size()}},
                     {{"byteLength", b.fallback_bytes},
                      {"extensions", {{"EXT_meshopt_compression", {{"fallback", true}}}}}}});
    extensions.push_back("EXT_meshopt_compression");
  }
  if (!extensions.empty()) gltf["extensionsRequired"] = extensions;
  extensions_used.insert(extensions_used.end(), extensions.begin(), extensions.end());
  gltf["extensionsUsed"] = extensions_used;
  std::string text = gltf.dump();
  text.resize((text.size() + 3) & ~size_t(3), ' ');
  std::vector<uint8_t> out;
  out.reserve(28 + text.size() + b.bin.size());
  put_u32(out, 0x46546C67);  // "glTF"
  put_u32(out, 2);
  put_u32(out, uint32_t(12 + 8 + text.size() + 8 + b.bin.size()));
  put_u32(out, uint32_t(text.size()));
  put_u32(out, 0x4E4F534A);  // "JSON"
  out.insert(out.end(), text.begin(), text.end());
  put_u32(out, uint32_t(b.bin.size()));
  put_u32(out, 0x004E4942);  // "BIN\0"
  out.insert(out.end(), b.bin.begin(), b.bin.end());
  return out;
}

}  // namespace stipple::tiler
