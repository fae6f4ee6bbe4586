// PlayCanvas SOG (version 2): meta.json and lossless WebP images of quantised attributes, one
// pixel a splat in row-major order, either bundled in a zip (.sog) or as files beside meta.json.
// The images are decoded with libwebp, which the web build lacks: there SOG is an error.
#include <algorithm>
#include <map>

#include <nlohmann/json.hpp>
#ifndef __EMSCRIPTEN__
#include <webp/decode.h>
#endif

#include "splat_detail.hpp"

namespace stipple::io::splat_detail {

#ifdef __EMSCRIPTEN__
bool sog_supported() {
  return false;
}

SplatSet decode_sog_zip(std::span<const uint8_t>, std::string_view name, const SplatLimits&) {
  fail("{}: SOG files cannot be read in the web build (no libwebp)", name);
}

SplatSet decode_sog_meta(std::span<const uint8_t>, std::string_view name,
                         const std::function<std::vector<uint8_t>(const std::string&)>&,
                         const SplatLimits&) {
  fail("{}: SOG files cannot be read in the web build (no libwebp)", name);
}
#else
namespace {

using json = nlohmann::json;

// The entries of a zip archive (stored or deflated; no ZIP64, no encryption), by name.
std::map<std::string, std::vector<uint8_t> > read_zip(std::span<const uint8_t> zip,
                                                      std::string_view name, size_t cap) {
  const size_t n = zip.size();
  if (n < 22) fail("{}: too short for a zip archive", name);
  // The end-of-central-directory record is in the last 22 + 65535 bytes (its comment).
  size_t eocd = std::string::npos;
  for (size_t at = n - 22 + 1; at-- > (n > 22 + 65535 ? n - 22 - 65535 : 0);)
    if (u32(zip.data() + at) == 0x06054b50) {
      eocd = at;
      break;
    }
  if (eocd == std::string::npos) fail("{}: zip archive has no end of central directory", name);
  const uint8_t* e = zip.data() + eocd;
  const uint16_t entries = u16(e + 10);
  const uint32_t cd_size = u32(e + 12), cd_offset = u32(e + 16);
  if (cd_offset > eocd || eocd - cd_offset < cd_size)
    fail("{}: zip central directory ({} bytes at {}) lies outside the archive", name, cd_size,
         cd_offset);
  std::map<std::string, std::vector<uint8_t> > files;
  size_t at = cd_offset, total = 0;
  const size_t cd_end = size_t(cd_offset) + cd_size;
  for (uint16_t k = 0; k < entries; ++k) {
    if (cd_end - at < 46 || u32(zip.data() + at) != 0x02014b50)
      fail("{}: zip central directory entry {} is damaged", name, k);
    const uint8_t* c = zip.data() + at;
    const uint16_t flags = u16(c + 8), method = u16(c + 10);
    const uint32_t packed = u32(c + 20), size = u32(c + 24);
    const uint16_t name_len = u16(c + 28), extra_len = u16(c + 30), comment_len = u16(c + 32);
    const uint32_t local = u32(c + 42);
    if (cd_end - at - 46 < size_t(name_len) + extra_len + comment_len)
      fail("{}: zip central directory entry {} runs past the directory", name, k);
    std::string entry(reinterpret_cast<const char*>(c + 46), name_len);
    at += 46 + size_t(name_len) + extra_len + comment_len;
    if (!entry.empty() && entry.back() == '/') continue;  // a folder
    if (flags & 1) fail("{}: zip entry {} is encrypted", name, entry);
    if (packed == 0xffffffffu || size == 0xffffffffu || local == 0xffffffffu)
      fail("{}: zip entry {} is ZIP64, which is not supported", name, entry);
    if (local > n || n - local < 30 || u32(zip.data() + local) != 0x04034b50)
      fail("{}: zip entry {} has no local header at {}", name, entry, local);
    const size_t data_at =
        size_t(local) + 30 + u16(zip.data() + local + 26) + u16(zip.data() + local + 28);
    if (data_at > n || n - data_at < packed)
      fail("{}: zip entry {} ({} bytes) runs past the end of the archive", name, entry, packed);
    if (size > cap || cap - size < total)
      fail("{}: zip entries inflate to more than {} bytes", name, cap);
    total += size;
    auto data = zip.subspan(data_at, packed);
    const std::string what = fmt::format("{}: {}", name, entry);
    if (method == 0) {
      if (packed != size) fail("{}: stored entry sizes differ", what);
      files[entry].assign(data.begin(), data.end());
    } else if (method == 8) {
      files[entry] = inflate_raw(data, size, what);
    } else {
      fail("{}: zip compression method {} is not supported (stored or deflate)", what, method);
    }
  }
  return files;
}

struct Image {
  int width = 0, height = 0;
  std::vector<uint8_t> rgba;
  const uint8_t* pixel(size_t i) const { return rgba.data() + i * 4; }
};

Image decode_webp(const std::vector<uint8_t>& bytes, const std::string& what, size_t min_pixels,
                  const SplatLimits& limits) {
  Image im;
  if (!WebPGetInfo(bytes.data(), bytes.size(), &im.width, &im.height))
    fail("{}: not a WebP image", what);
  const size_t pixels = size_t(im.width) * size_t(im.height);
  if (pixels < min_pixels)
    fail("{}: {}x{} pixels cannot hold {} values", what, im.width, im.height, min_pixels);
  if (pixels > limits.max_splats * 16 || pixels * 4 > limits.max_inflated_bytes)
    fail("{}: {}x{} pixels exceed the limit", what, im.width, im.height);
  im.rgba.resize(pixels * 4);
  if (!WebPDecodeRGBAInto(bytes.data(), bytes.size(), im.rgba.data(), im.rgba.size(), im.width * 4))
    fail("{}: WebP image cannot be decoded", what);
  return im;
}

std::vector<float> numbers(const json& meta, const char* section, const char* key, size_t count,
                           std::string_view name) {
  const json& a = meta.at(section).at(key);
  if (!a.is_array() || a.size() != count)
    fail("{}: meta.json {}.{} is not {} numbers", name, section, key, count);
  std::vector<float> v;
  for (const auto& x : a) {
    if (!x.is_number()) fail("{}: meta.json {}.{} holds a non-number", name, section, key);
    v.push_back(x.get<float>());
  }
  return v;
}

SplatSet decode_meta(std::span<const uint8_t> meta_bytes, std::string_view name,
                     const std::function<std::vector<uint8_t>(const std::string&)>& file,
                     const SplatLimits& limits) {
  json meta = json::parse(meta_bytes.begin(), meta_bytes.end(), nullptr, false);
  if (meta.is_discarded() || !meta.is_object()) fail("{}: meta.json is not valid JSON", name);
  const int version = meta.value("version", 1);
  if (version != 2) fail("{}: SOG version {} is not supported (version 2 is read)", name, version);
  if (!meta.contains("count") || !meta["count"].is_number_unsigned())
    fail("{}: meta.json has no count", name);
  const size_t n = meta["count"].get<size_t>();
  if (n > limits.max_splats)
    fail("{}: {} splats exceed the limit of {}", name, n, limits.max_splats);
  auto image = [&](const char* section, size_t index, size_t min_pixels) {
    const json& files = meta.at(section).at("files");
    if (!files.is_array() || files.size() <= index || !files[index].is_string())
      fail("{}: meta.json {}.files does not name image {}", name, section, index);
    const std::string f = files[index].get<std::string>();
    return decode_webp(file(f), fmt::format("{}: {}", name, f), min_pixels, limits);
  };
  const auto mins = numbers(meta, "means", "mins", 3, name);
  const auto maxs = numbers(meta, "means", "maxs", 3, name);
  const auto scale_book = numbers(meta, "scales", "codebook", 256, name);
  const auto dc_book = numbers(meta, "sh0", "codebook", 256, name);
  int degree = 0;
  size_t palette = 0;
  std::vector<float> sh_book;
  if (meta.contains("shN")) {
    const json& shn = meta["shN"];
    degree = shn.value("bands", 0);
    if (degree < 1 || degree > 3) fail("{}: meta.json shN.bands {} is not 1..3", name, degree);
    palette = shn.value("count", size_t(0));
    if (palette == 0 || palette > 65536) fail("{}: meta.json shN.count is not 1..65536", name);
    sh_book = numbers(meta, "shN", "codebook", 256, name);
  }
  SplatSet s;
  s.format = "SOG v2";
  resize_splats(s, n, degree, limits, name);
  const Image lo = image("means", 0, n), hi = image("means", 1, n);
  const Image scales = image("scales", 0, n), quats = image("quats", 0, n),
              sh0 = image("sh0", 0, n);
  for (size_t i = 0; i < n; ++i) {
    const uint8_t *l = lo.pixel(i), *u = hi.pixel(i);
    for (int k = 0; k < 3; ++k) {
      // 16 bits over [min, max] of a log-transformed coordinate: sign(v) (e^|v| - 1).
      const float t = float(l[k] | (u[k] << 8)) / 65535.0f;
      const float v = mins[size_t(k)] + (maxs[size_t(k)] - mins[size_t(k)]) * t;
      s.positions[i][k] = std::copysign(std::expm1(std::fabs(v)), v);
      s.scales[i][k] = std::exp(scale_book[scales.pixel(i)[k]]);
      s.sh_dc[i][k] = dc_book[sh0.pixel(i)[k]];
    }
    s.opacities[i] = float(sh0.pixel(i)[3]) / 255.0f;
    // Three components in [-1/sqrt2, 1/sqrt2] and, in alpha, 252 + the index of the largest
    // (in w, x, y, z order).
    const uint8_t* q = quats.pixel(i);
    const int largest = q[3] - 252;
    if (largest < 0 || largest > 3) fail("{}: quats.webp pixel {} has mode {}", name, i, q[3]);
    float abc[3], sum = 0.0f;
    for (int k = 0; k < 3; ++k) {
      abc[k] = (float(q[k]) / 255.0f - 0.5f) * 2.0f / std::sqrt(2.0f);
      sum += abc[k] * abc[k];
    }
    float wxyz[4];
    for (int k = 0, j = 0; k < 4; ++k)
      wxyz[k] = k == largest ? std::sqrt(std::max(0.0f, 1.0f - sum)) : abc[j++];
    s.rotations[i] = unit_quaternion(wxyz[1], wxyz[2], wxyz[3], wxyz[0]);
  }
  if (degree > 0) {
    // Labels (16 bits in R, G) index a palette whose entry e holds its coefficients in row
    // e / 64, pixels (e % 64) * coefficients onwards; each channel indexes the codebook.
    const size_t coeffs = s.rest_count();
    const Image labels = image("shN", 1, n);
    const Image centroids = image("shN", 0, 0);
    if (size_t(centroids.width) < 64 * coeffs || size_t(centroids.height) < (palette + 63) / 64)
      fail("{}: shN centroids image of {}x{} cannot hold {} palette entries", name, centroids.width,
           centroids.height, palette);
    for (size_t i = 0; i < n; ++i) {
      const size_t e = size_t(labels.pixel(i)[0]) | (size_t(labels.pixel(i)[1]) << 8);
      if (e >= palette) fail("{}: shN label {} of splat {} is past the palette", name, e, i);
      for (size_t k = 0; k < coeffs; ++k) {
        const uint8_t* c =
            centroids.pixel((e / 64) * size_t(centroids.width) + (e % 64) * coeffs + k);
        s.sh_rest[i * coeffs + k] = {sh_book[c[0]], sh_book[c[1]], sh_book[c[2]]};
      }
    }
  }
  return s;
}

}  // namespace

bool sog_supported() {
  return true;
}

SplatSet decode_sog_meta(std::span<const uint8_t> meta, std::string_view name,
                         const std::function<std::vector<uint8_t>(const std::string&)>& file,
                         const SplatLimits& limits) {
  try {
    return decode_meta(meta, name, file, limits);
  } catch (const json::exception& e) {
    fail("{}: meta.json lacks a field or has the wrong type: {}", name, e.what());
  }
}

SplatSet decode_sog_zip(std::span<const uint8_t> bytes, std::string_view name,
                        const SplatLimits& limits) {
  auto files = read_zip(bytes, name, limits.max_inflated_bytes);
  // The files lie at the archive's root (or, written by some tools, in one folder).
  std::string prefix;
  if (!files.count("meta.json")) {
    for (const auto& [entry, data] : files)
      if (entry.size() > 10 && entry.substr(entry.size() - 10) == "/meta.json")
        prefix = entry.substr(0, entry.size() - 9);
    if (prefix.empty()) fail("{}: the zip archive holds no meta.json", name);
  }
  return decode_sog_meta(
      files[prefix + "meta.json"], name,
      [&](const std::string& f) {
        auto it = files.find(prefix + f);
        if (it == files.end()) fail("{}: the archive lacks {}", name, f);
        return it->second;
      },
      limits);
}
#endif

}  // namespace stipple::io::splat_detail
