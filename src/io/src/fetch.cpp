#include "stipple/io/fetch.hpp"

#include <algorithm>
#include <cctype>
#include <chrono>
#include <cstdio>
#include <mutex>
#include <thread>

#include <curl/curl.h>

#include "fetch_detail.hpp"
#include "stipple/core/error.hpp"
#include "stipple/core/log.hpp"

namespace stipple::io {
namespace {

void global_init() {
  static std::once_flag once;
  std::call_once(once, [] { curl_global_init(CURL_GLOBAL_DEFAULT); });
}

// One easy handle per thread: libcurl keeps that handle's connections open, so repeated requests
// to one server reuse them (keep-alive) without locking a shared cache.
struct EasyHandle {
  CURL* curl = nullptr;
  EasyHandle() {
    global_init();
    curl = curl_easy_init();
  }
  ~EasyHandle() {
    if (curl) curl_easy_cleanup(curl);
  }
};

struct Sink {
  std::vector<uint8_t>* body;
  uint64_t cap;
  bool overflow = false;
};

// The Content-Range header of a ranged answer: "bytes FIRST-LAST/TOTAL" (TOTAL may be "*").
struct ContentRange {
  bool seen = false;
  uint64_t first = 0, last = 0, total = 0;
};

size_t read_header(char* data, size_t size, size_t count, void* user) {
  auto* range = static_cast<ContentRange*>(user);
  const size_t n = size * count;
  std::string_view line(data, n);
  constexpr std::string_view name = "content-range:";
  if (line.size() > name.size()) {
    bool match = true;
    for (size_t i = 0; i < name.size() && match; ++i)
      match = std::tolower(static_cast<unsigned char>(line[i])) == name[i];
    if (match) {
      unsigned long long a = 0, b = 0, t = 0;
      std::string value(line.substr(name.size()));
      if (std::sscanf(value.c_str(), " bytes %llu-%llu/%llu", &a, &b, &t) >= 2) {
        range->seen = true;
        range->first = a;
        range->last = b;
        range->total = t;
      }
    }
  }
  return n;
}

size_t write_body(char* data, size_t size, size_t count, void* user) {
  auto* sink = static_cast<Sink*>(user);
  size_t n = size * count;
  if (sink->body->size() + n > sink->cap) {
    sink->overflow = true;
    return 0;  // aborts the transfer with CURLE_WRITE_ERROR
  }
  sink->body->insert(sink->body->end(), data, data + n);
  return n;
}

bool transient(CURLcode code) {
  switch (code) {
    case CURLE_COULDNT_CONNECT:
    case CURLE_OPERATION_TIMEDOUT:
    case CURLE_RECV_ERROR:
    case CURLE_SEND_ERROR:
    case CURLE_GOT_NOTHING:
    case CURLE_PARTIAL_FILE:
    case CURLE_HTTP2:
    case CURLE_HTTP2_STREAM:
    case CURLE_COULDNT_RESOLVE_HOST:
      return true;
    default:
      return false;
  }
}

}  // namespace

using detail::read_file;
using detail::read_file_range;
using detail::starts_with_ci;

std::vector<uint8_t> fetch(const std::string& uri, const FetchOptions& options, FetchStats* stats) {
  ByteRange range;
  const bool ranged = parse_range_uri(uri, &range);
  if (!is_url(uri)) {
    if (ranged) return read_file_range(uri, range, options, stats);
    if (stats) stats->attempts = 1;
    return read_file(uri.substr(0, uri.find('#')), options);  // fields after '#' are ours
  }
  if (ranged && range.size > options.max_bytes)
    fail("{}: a read of {} bytes is more than the limit of {} bytes", uri, range.size,
         options.max_bytes);
  const std::string url = ranged ? uri.substr(0, uri.find('#')) : uri;
  thread_local EasyHandle handle;
  CURL* curl = handle.curl;
  if (!curl) fail("{}: cannot create an HTTP client", uri);
  long backoff = options.backoff_initial_ms;
  for (int attempt = 0;; ++attempt) {
    std::vector<uint8_t> body;
    // A ranged read stops after the range's size: a server ignoring the range is found out
    // without downloading the whole file.
    Sink sink{&body, ranged ? range.size : options.max_bytes};
    ContentRange content_range;
    char error_text[CURL_ERROR_SIZE] = {0};
    curl_easy_reset(curl);  // keeps the connection cache
    curl_easy_setopt(curl, CURLOPT_URL, url.c_str());
    const std::string range_text =
        ranged ? fmt::format("{}-{}", range.offset, range.offset + range.size - 1) : "";
    if (ranged) {
      curl_easy_setopt(curl, CURLOPT_RANGE, range_text.c_str());
      curl_easy_setopt(curl, CURLOPT_HEADERFUNCTION, read_header);
      curl_easy_setopt(curl, CURLOPT_HEADERDATA, &content_range);
    }
    curl_easy_setopt(curl, CURLOPT_FOLLOWLOCATION, 1L);
    curl_easy_setopt(curl, CURLOPT_MAXREDIRS, 8L);
    curl_easy_setopt(curl, CURLOPT_NOSIGNAL, 1L);  // worker threads: no SIGALRM for timeouts
    curl_easy_setopt(curl, CURLOPT_CONNECTTIMEOUT_MS, options.connect_timeout_ms);
    curl_easy_setopt(curl, CURLOPT_LOW_SPEED_LIMIT, options.low_speed_bytes);
    curl_easy_setopt(curl, CURLOPT_LOW_SPEED_TIME, options.low_speed_time_s);
    curl_easy_setopt(curl, CURLOPT_TIMEOUT_MS, options.total_timeout_ms);
    // Every encoding libcurl decodes, except on ranges: a range is of the stored bytes.
    if (!ranged) {
      curl_easy_setopt(curl, CURLOPT_ACCEPT_ENCODING, "");
      curl_easy_setopt(curl, CURLOPT_MAXFILESIZE_LARGE, curl_off_t(options.max_bytes));
    }
    curl_easy_setopt(curl, CURLOPT_WRITEFUNCTION, write_body);
    curl_easy_setopt(curl, CURLOPT_WRITEDATA, &sink);
    curl_easy_setopt(curl, CURLOPT_ERRORBUFFER, error_text);
    curl_easy_setopt(curl, CURLOPT_USERAGENT, "stipple/0.1");
    CURLcode code = curl_easy_perform(curl);
    long status = 0;
    curl_easy_getinfo(curl, CURLINFO_RESPONSE_CODE, &status);
    if (stats) {
      stats->attempts = attempt + 1;
      stats->http_status = status;
    }
    std::string problem;
    bool retry = false;
    if (ranged && (status == 200 || (status >= 200 && status < 300 && status != 206)))
      fail(
          "{}: the server ignores range requests (HTTP {} to a request for bytes {}); COPC and "
          "other ranged reads need a server with byte-range support",
          url, status, range_text);
    if (ranged && status == 416)
      fail("{}: bytes {} are past the end of the file (HTTP 416)", url, range_text);
    if (sink.overflow || code == CURLE_FILESIZE_EXCEEDED) {
      fail("{}: response larger than the limit of {} bytes", uri, options.max_bytes);
    } else if (code != CURLE_OK) {
      problem = fmt::format("{}", error_text[0] ? error_text : curl_easy_strerror(code));
      retry = transient(code);
    } else if (status >= 500 || status == 429 || status == 408) {
      problem = fmt::format("HTTP {}", status);
      retry = true;
    } else if (status >= 400) {
      fail("{}: HTTP {}{}", uri, status, status == 404 ? " (not found)" : "");
    } else if (ranged) {
      if (!content_range.seen || content_range.first != range.offset || body.size() != range.size)
        fail("{}: the server answered bytes {} with {} bytes{}, not the range asked for", url,
             range_text, body.size(),
             content_range.seen ? fmt::format(" at {}-{}", content_range.first, content_range.last)
                                : std::string(" without a Content-Range"));
      if (stats) stats->total_size = content_range.total;
      return body;
    } else {
      const char* type = nullptr;
      curl_easy_getinfo(curl, CURLINFO_CONTENT_TYPE, &type);
      if (options.reject_html && ((type && starts_with_ci(type, "text/html")) ||
                                  looks_like_html(body.data(), body.size())))
        fail("{}: the server answered with an HTML page, not tile data", uri);
      return body;
    }
    if (!retry || attempt >= options.max_retries)
      fail("{}: {}{}", uri, problem,
           attempt > 0 ? fmt::format(" (after {} tries)", attempt + 1) : "");
    STIPPLE_DEBUG("{}: {}; retrying in {} ms", uri, problem, backoff);
    std::this_thread::sleep_for(std::chrono::milliseconds(backoff));
    backoff *= 2;
  }
}

}  // namespace stipple::io
