#pragma once
// Reading bytes from a local path or an http(s):// URL, with the limits a streaming client needs:
// timeouts, retries with exponential back-off on transient faults, a size cap per response and a
// check that a server did not answer with an HTML page where data was expected.
#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

namespace stipple::io {

struct FetchOptions {
  long connect_timeout_ms = 10'000;
  // A transfer slower than low_speed_bytes per second for low_speed_time_s is aborted (a stalled
  // server); total_timeout_ms (0: none) bounds the whole transfer.
  long low_speed_bytes = 1024;
  long low_speed_time_s = 15;
  long total_timeout_ms = 0;
  int max_retries = 3;            // on 5xx, 429, connection resets and timeouts; never on 4xx
  long backoff_initial_ms = 200;  // doubled after every failed try
  uint64_t max_bytes = 512ull << 20;
  bool reject_html = true;  // a body that is an HTML page is an error (a portal, a 200 "not found")
};

struct FetchStats {
  int attempts = 0;
  long http_status = 0;
  uint64_t total_size = 0;  // ranged reads: the whole file's size (Content-Range, or the file's)
};

// A byte range of a resource, named in its URI's fragment as `#bytes=FIRST-LAST` (inclusive, as
// in HTTP; other `&key=value` fields may follow), so range reads pass through a Fetcher as plain
// URIs. Servers never see fragments.
struct ByteRange {
  uint64_t offset = 0, size = 0;
};
std::string range_uri(const std::string& uri, uint64_t offset, uint64_t size);
// Whether `uri` names a range; its value in `range`.
bool parse_range_uri(const std::string& uri, ByteRange* range);
// The value of `key` in the fragment's `&`-separated fields; empty when absent.
std::string fragment_field(const std::string& uri, std::string_view key);

bool is_url(std::string_view uri);
// Resolves `relative` against the URI (file path or URL) of the document that referenced it.
// Absolute URLs, absolute paths and data: URIs are returned unchanged.
std::string resolve_uri(const std::string& base_document, const std::string& relative);
// `uri` without query and fragment, for extension checks.
std::string uri_path(const std::string& uri);

// Throws stipple::Error naming the URI and the problem. A range URI reads exactly that range: a
// positional read of a local file, or an HTTP Range request that must be answered with 206 and
// the range asked for (a server that ignores ranges is an error, stopped after the range's size
// instead of downloading the whole file); a range past the end is an error.
std::vector<uint8_t> fetch(const std::string& uri, const FetchOptions& options = {},
                           FetchStats* stats = nullptr);

// Whether the bytes look like an HTML document (leading whitespace and BOM skipped).
bool looks_like_html(const uint8_t* data, size_t size);

}  // namespace stipple::io
