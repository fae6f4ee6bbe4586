#pragma once
// What io::fetch shares between its two builds: local files and ranges of them, prefix checks,
// and the HTTP client each build supplies (fetch.cpp: libcurl; fetch_web.cpp: the browser's
// XMLHttpRequest and fetch), which fetch() drives through fetch_http (fetch_policy.hpp).
#include <string>
#include <string_view>
#include <vector>

#include "stipple/io/fetch.hpp"
#include "stipple/io/fetch_policy.hpp"

namespace stipple::io::detail {

bool starts_with_ci(std::string_view s, std::string_view prefix);
std::vector<uint8_t> read_file(const std::string& path, const FetchOptions& options);
std::vector<uint8_t> read_file_range(const std::string& uri, const ByteRange& r,
                                     const FetchOptions& options, FetchStats* stats);

// The build's client: one request, reported as it came (no retries, no checks of its own).
HttpAnswer perform_http(const HttpRequest& request);
// Waits out a back-off where the build's client may wait.
void sleep_ms(long ms);

}  // namespace stipple::io::detail
