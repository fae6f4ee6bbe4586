#pragma once
// Integer fields of untrusted JSON metadata (Potree, EPT). nlohmann's value(key, 0) and
// get<int>() convert a floating-point number such as 8.9e82 to int, which is undefined
// behaviour: these read integers only, and in range, or fail naming the file and the key.
// Private to the io module.
#include <cstdint>
#include <limits>
#include <string>

#include <nlohmann/json.hpp>

#include "stipple/core/error.hpp"

namespace stipple::io::json_fields {

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
