#include "stipple/tiler/splat_glb.hpp"

#include <algorithm>
#include <cstring>
#include <string>

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include "stipple/core/error.hpp"
#include "stipple/tiler/spz_writer.hpp"

namespace stipple::tiler {

namespace {

using nlohmann::json;

constexpr int kUnsignedByte = 5121, kFloat = 5126;

void put_u32(std::vector<uint8_t>& out, uint32_t v) {
  uint8_t b[4];
  std::memcpy(b, &v, 4);
  out.insert(out.end(), b, b + 4);
}

std::vector<uint8_t> pack_glb(const json& gltf, const std::vector<uint8_t>& bin) {
  std::string text = gltf.dump();
  text.resize((text.size() + 3) & ~size_t(3), ' ');
  const size_t padded = (bin.size() + 3) & ~size_t(3);
  if (28 + text.size() + padded > 0xffffffffu)
    fail("a splat tile of {} bytes is more than a glb holds (4 GiB); use smaller leaves",
         28 + text.size() + padded);
  std::vector<uint8_t> out;
  out.reserve(28 + text.size() + padded);
  put_u32(out, 0x46546C67);  // "glTF"
  put_u32(out, 2);
  put_u32(out, uint32_t(12 + 8 + text.size() + 8 + padded));
  put_u32(out, uint32_t(text.size()));
  put_u32(out, 0x4E4F534A);  // "JSON"
  out.insert(out.end(), text.begin(), text.end());
  put_u32(out, uint32_t(padded));
  put_u32(out, 0x004E4942);  // "BIN\0"
  out.insert(out.end(), bin.begin(), bin.end());
  out.resize(out.size() + padded - bin.size(), 0);
  return out;
}

std::string sh_name(int l, int c) {
  return fmt::format("KHR_gaussian_splatting:SH_DEGREE_{}_COEF_{}", l, c);
}

}  // namespace

std::vector<uint8_t> write_splat_glb(const io::SplatSet& in, SplatCompression compression) {
  const size_t n = in.size(), rc = in.rest_count();
  glm::dvec3 lo(1e300), hi(-1e300);
  for (const glm::vec3& p : in.positions) {
    lo = glm::min(lo, glm::dvec3(p));
    hi = glm::max(hi, glm::dvec3(p));
  }
  const glm::dvec3 centre = n ? (lo + hi) * 0.5 : glm::dvec3(0);
  io::SplatSet local = in;
  glm::vec3 fmin(1e30f), fmax(-1e30f);
  for (glm::vec3& p : local.positions) {
    p = glm::vec3(glm::dvec3(p) - centre);
    fmin = glm::min(fmin, p);
    fmax = glm::max(fmax, p);
  }
  if (n == 0) fmin = fmax = glm::vec3(0);
  json accessors = json::array(), views = json::array(), attributes = json::object();
  std::vector<uint8_t> bin;
  auto accessor = [&](int component, const char* type, bool normalized = false) {
    json a = {{"componentType", component}, {"count", n}, {"type", type}};
    if (normalized) a["normalized"] = true;
    accessors.push_back(a);
    return int(accessors.size() - 1);
  };
  // A tightly packed float view of `comps` floats a splat, element i from fill(i, dst).
  auto float_view = [&](int comps, auto fill) {
    const size_t offset = bin.size();
    bin.resize(offset + n * size_t(comps) * 4, 0);
    for (size_t i = 0; i < n; ++i) {
      float v[4];
      fill(i, v);
      std::memcpy(bin.data() + offset + i * size_t(comps) * 4, v, size_t(comps) * 4);
    }
    views.push_back({{"buffer", 0},
                     {"byteOffset", offset},
                     {"byteLength", n * size_t(comps) * 4},
                     {"target", 34962}});
    return int(views.size() - 1);
  };
  json splatting = {{"kernel", "ellipse"}, {"colorSpace", "srgb_rec709_display"}};
  std::vector<std::string> used = {"KHR_gaussian_splatting"}, required;
  const int pos = accessor(kFloat, "VEC3");
  accessors[pos]["min"] = {fmin.x, fmin.y, fmin.z};
  accessors[pos]["max"] = {fmax.x, fmax.y, fmax.z};
  attributes["POSITION"] = pos;
  if (compression == SplatCompression::Spz) {
    attributes["COLOR_0"] = accessor(kUnsignedByte, "VEC4", true);
    attributes["KHR_gaussian_splatting:ROTATION"] = accessor(kFloat, "VEC4");
    attributes["KHR_gaussian_splatting:SCALE"] = accessor(kFloat, "VEC3");
    for (int l = 1; l <= in.sh_degree; ++l)
      for (int c = 0; c < 2 * l + 1; ++c) attributes[sh_name(l, c)] = accessor(kFloat, "VEC3");
    bin = encode_spz(local);
    views.push_back({{"buffer", 0}, {"byteOffset", 0}, {"byteLength", bin.size()}});
    splatting["extensions"] = {{"KHR_gaussian_splatting_compression_spz_2", {{"bufferView", 0}}}};
    used.push_back("KHR_gaussian_splatting_compression_spz_2");
    required = used;
  } else {
    int v = float_view(3, [&](size_t i, float* d) { std::memcpy(d, &local.positions[i], 12); });
    accessors[pos]["bufferView"] = v;
    v = float_view(4, [&](size_t i, float* d) { std::memcpy(d, &local.rotations[i], 16); });
    attributes["KHR_gaussian_splatting:ROTATION"] = accessor(kFloat, "VEC4");
    accessors.back()["bufferView"] = v;
    v = float_view(3, [&](size_t i, float* d) { std::memcpy(d, &local.scales[i], 12); });
    attributes["KHR_gaussian_splatting:SCALE"] = accessor(kFloat, "VEC3");
    accessors.back()["bufferView"] = v;
    v = float_view(1, [&](size_t i, float* d) { d[0] = local.opacities[i]; });
    attributes["KHR_gaussian_splatting:OPACITY"] = accessor(kFloat, "SCALAR");
    accessors.back()["bufferView"] = v;
    v = float_view(3, [&](size_t i, float* d) { std::memcpy(d, &local.sh_dc[i], 12); });
    attributes[sh_name(0, 0)] = accessor(kFloat, "VEC3");
    accessors.back()["bufferView"] = v;
    size_t k = 0;
    for (int l = 1; l <= in.sh_degree; ++l)
      for (int c = 0; c < 2 * l + 1; ++c, ++k) {
        v = float_view(3,
                       [&](size_t i, float* d) { std::memcpy(d, &local.sh_rest[i * rc + k], 12); });
        attributes[sh_name(l, c)] = accessor(kFloat, "VEC3");
        accessors.back()["bufferView"] = v;
      }
  }
  json primitive = {{"attributes", attributes},
                    {"mode", 0},
                    {"extensions", {{"KHR_gaussian_splatting", splatting}}}};
  // A matrix, not a translation: CesiumJS 1.145 takes a splat tile's transform from the first
  // node's matrix only (GaussianSplat3DTileContent), and fails to render without one.
  json node = {{"mesh", 0},
               {"matrix", {1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, centre.x, centre.y, centre.z, 1}}};
  json gltf = {{"asset", {{"version", "2.0"}, {"generator", "stipple tile"}}},
               {"scene", 0},
               {"scenes", json::array({{{"nodes", {0}}}})},
               {"nodes", json::array({node})},
               {"meshes", json::array({{{"primitives", json::array({primitive})}}})},
               {"accessors", accessors},
               {"bufferViews", views},
               {"buffers", json::array({{{"byteLength", (bin.size() + 3) & ~size_t(3)}}})},
               {"extensionsUsed", used}};
  if (!required.empty()) gltf["extensionsRequired"] = required;
  return pack_glb(gltf, bin);
}

}  // namespace stipple::tiler
