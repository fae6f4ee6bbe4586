#include "stipple/io/fetch.hpp"

#include <algorithm>
#include <cctype>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <mutex>
#include <thread>

#include <curl/curl.h>

#include "stipple/core/error.hpp"
#include "stipple/core/log.hpp"

namespace stipple::io {
namespace {

bool starts_with_ci(std::string_view s, std::string_view prefix) {
  if (s.size() < prefix.size()) return false;
  for (size_t i = 0; i < prefix.size(); ++i)
    if (std::tolower(static_cast<unsigned char>(s[i])) != prefix[i]) return false;
  return true;
}

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

std::vector<uint8_t> read_file(const std::string& path, const FetchOptions& options) {
  std::error_code ec;
  auto size = std::filesystem::file_size(path, ec);
  if (ec) fail("{}: cannot open ({})", path, ec.message());
  if (size > options.max_bytes)
    fail("{}: {} bytes is more than the limit of {} bytes per file", path, size, options.max_bytes);
  std::ifstream in(path, std::ios::binary);
  if (!in) fail("{}: cannot open", path);
  std::vector<uint8_t> data(size);
  in.read(reinterpret_cast<char*>(data.data()), std::streamsize(size));
  if (in.gcount() != std::streamsize(size)) fail("{}: read error", path);
  return data;
}

std::vector<uint8_t> read_file_range(const std::string& uri, const ByteRange& r,
                                     const FetchOptions& options, FetchStats* stats) {
  const std::string path = uri_path(uri);
  std::error_code ec;
  const uint64_t size = std::filesystem::file_size(path, ec);
  if (ec) fail("{}: cannot open ({})", path, ec.message());
  if (r.size > options.max_bytes)
    fail("{}: a read of {} bytes is more than the limit of {} bytes", path, r.size,
         options.max_bytes);
  if (r.offset > size || r.size > size - r.offset)
    fail("{}: bytes {}-{} are past the end of the file ({} bytes)", path, r.offset,
         r.offset + r.size - 1, size);
  if (stats) {
    stats->attempts = 1;
    stats->total_size = size;
  }
  std::ifstream in(path, std::ios::binary);
  if (!in) fail("{}: cannot open", path);
  std::vector<uint8_t> data(r.size);
  in.seekg(std::streamoff(r.offset));
  in.read(reinterpret_cast<char*>(data.data()), std::streamsize(r.size));
  if (in.gcount() != std::streamsize(r.size)) fail("{}: read error", path);
  return data;
}

}  // namespace

std::string range_uri(const std::string& uri, uint64_t offset, uint64_t size) {
  const size_t hash = uri.find('#');
  return fmt::format("{}#bytes={}-{}", uri.substr(0, hash), offset,
                     size > 0 ? offset + size - 1 : offset);
}

std::string fragment_field(const std::string& uri, std::string_view key) {
  const size_t hash = uri.find('#');
  if (hash == std::string::npos) return {};
  std::string_view rest = std::string_view(uri).substr(hash + 1);
  while (!rest.empty()) {
    const size_t amp = rest.find('&');
    std::string_view field = rest.substr(0, amp);
    if (field.size() > key.size() && field.substr(0, key.size()) == key && field[key.size()] == '=')
      return std::string(field.substr(key.size() + 1));
    if (amp == std::string_view::npos) break;
    rest = rest.substr(amp + 1);
  }
  return {};
}

bool parse_range_uri(const std::string& uri, ByteRange* range) {
  const std::string value = fragment_field(uri, "bytes");
  if (value.empty()) return false;
  unsigned long long first = 0, last = 0;
  char tail = 0;
  if (std::sscanf(value.c_str(), "%llu-%llu%c", &first, &last, &tail) != 2 || last < first)
    return false;
  if (range) *range = {first, last - first + 1};
  return true;
}

bool is_url(std::string_view uri) {
  return starts_with_ci(uri, "http://") || starts_with_ci(uri, "https://");
}

std::string uri_path(const std::string& uri) {
  size_t end = uri.find_first_of(is_url(uri) ? "?#" : "#");
  return uri.substr(0, end);
}

std::string resolve_uri(const std::string& base_document, const std::string& relative) {
  if (relative.empty()) return base_document;
  if (is_url(relative) || starts_with_ci(relative, "data:") || relative.front() == '/') {
    // An absolute path on a URL base is relative to the server root.
    if (relative.front() == '/' && is_url(base_document)) {
      size_t scheme = base_document.find("://");
      size_t host_end = base_document.find('/', scheme + 3);
      return base_document.substr(0, host_end) + relative;
    }
    return relative;
  }
  std::string base = uri_path(base_document);
  if (is_url(base)) {
    std::string query;
    size_t q = base_document.find('?');
    // The tileset's query (an API key, a session) is passed on to what it references, as
    // CesiumJS does, unless the reference has its own.
    if (q != std::string::npos && relative.find('?') == std::string::npos)
      query = base_document.substr(q, base_document.find('#', q) - q);
    size_t slash = base.rfind('/');
    std::string dir = base.substr(0, slash + 1);
    // Collapse ./ and ../ segments of the path part.
    size_t scheme = dir.find("://");
    size_t path_start = dir.find('/', scheme + 3);
    if (path_start == std::string::npos) {
      dir += '/';
      path_start = dir.size() - 1;
    }
    std::string root = dir.substr(0, path_start);
    std::vector<std::string> parts;
    std::string path = dir.substr(path_start) + relative;
    size_t end = path.find_first_of("?#");
    std::string tail = end == std::string::npos ? "" : path.substr(end);
    path = path.substr(0, end);
    size_t start = 0;
    while (start <= path.size()) {
      size_t next = path.find('/', start);
      std::string seg =
          path.substr(start, next == std::string::npos ? std::string::npos : next - start);
      if (seg == "..") {
        if (!parts.empty()) parts.pop_back();
      } else if (seg != "." && !(seg.empty() && next != std::string::npos)) {
        parts.push_back(seg);
      }
      if (next == std::string::npos) break;
      start = next + 1;
    }
    std::string out = root;
    for (const auto& p : parts) out += "/" + p;
    return out + tail + (tail.empty() ? query : "");
  }
  std::filesystem::path dir = std::filesystem::path(base).parent_path();
  return (dir / relative).lexically_normal().string();
}

bool looks_like_html(const uint8_t* data, size_t size) {
  size_t i = 0;
  if (size >= 3 && data[0] == 0xEF && data[1] == 0xBB && data[2] == 0xBF) i = 3;
  while (i < size && std::isspace(data[i])) ++i;
  std::string_view head(reinterpret_cast<const char*>(data) + i, std::min<size_t>(size - i, 16));
  return starts_with_ci(head, "<!doctype html") || starts_with_ci(head, "<html") ||
         starts_with_ci(head, "<head") || starts_with_ci(head, "<body");
}

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
