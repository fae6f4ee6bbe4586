#pragma once
// What io::fetch shares between its two implementations (fetch.cpp: libcurl; fetch_web.cpp: the
// browser's XMLHttpRequest and fetch): local files and ranges of them, prefix checks.
#include <string>
#include <string_view>
#include <vector>

#include "stipple/io/fetch.hpp"

namespace stipple::io::detail {

bool starts_with_ci(std::string_view s, std::string_view prefix);
std::vector<uint8_t> read_file(const std::string& path, const FetchOptions& options);
std::vector<uint8_t> read_file_range(const std::string& uri, const ByteRange& r,
                                     const FetchOptions& options, FetchStats* stats);

}  // namespace stipple::io::detail
