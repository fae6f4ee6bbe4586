#pragma once
// Untrusted JSON metadata (Potree, EPT): opened with a size cap as an object, and its integer
// fields. nlohmann's value(key, 0) and get<int>() convert a floating-point number such as
// 8.9e82 to int, which is undefined behaviour: these read integers only, and in range, or fail
// naming the file and the key. Private to the io module.
#include <cstdint>
#include <limits>
#include <span>
#include <string>

#include <nlohmann/json.hpp>

#include "stipple/core/error.hpp"

namespace stipple::io::json_fields {

// `bytes` parsed as a JSON object of at most 64 MiB, or fail naming `uri`.
inline nlohmann::json metadata_object(std::span<const uint8_t> bytes, const std::string& uri) {
  if (bytes.size() > (64u << 20)) fail("{}: metadata of {} bytes is too large", uri, bytes.size());
  nlohmann::json j = nlohmann::json::parse(bytes.begin(), bytes.end(), nullptr, false);
  if (!j.is_object()) fail("{}: not a JSON object", uri);
  return j;
}

// `o[key]` as an integer in [lo, hi]; `fallback` where the key is absent.
inline int64_t integer(const nlohmann::json& o, const char* key, int64_t fallback,
                       const std::string& uri, int64_t lo = std::numeric_limits<int32_t>::min(),
                       int64_t hi = std::numeric_limits<int32_t>::max()) {
  if (!o.is_object() || !o.contains(key)) return fallback;
  const nlohmann::json& v = o[key];
  if (!v.is_number_integer()) fail("{}: {} is not an integer", uri, key);
  const bool above =
      v.is_number_unsigned() ? v.get<uint64_t>() > uint64_t(hi) : v.get<int64_t>() > hi;
  if (above || (!v.is_number_unsigned() && v.get<int64_t>() < lo))
    fail("{}: {} is outside {}-{}", uri, key, lo, hi);
  return v.get<int64_t>();
}

}  // namespace stipple::io::json_fields
