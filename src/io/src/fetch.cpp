// io::fetch's HTTP client in the native build: libcurl, one request per call (perform_http);
// retries and the checks of the answer are fetch_policy.cpp's.
#include <chrono>
#include <mutex>
#include <thread>

#include <curl/curl.h>

#include "fetch_detail.hpp"
#include "stipple/core/error.hpp"

namespace stipple::io::detail {
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

// The value of header `name` of the last response (after redirects); empty when absent.
std::string header(CURL* curl, const char* name) {
  curl_header* h = nullptr;
  if (curl_easy_header(curl, name, 0, CURLH_HEADER, -1, &h) != CURLHE_OK || !h) return {};
  return h->value;
}

}  // namespace

HttpAnswer perform_http(const HttpRequest& request) {
  thread_local EasyHandle handle;
  CURL* curl = handle.curl;
  if (!curl) fail("{}: cannot create an HTTP client", request.uri);
  HttpAnswer answer;
  // A ranged read stops after the range's size: a server ignoring the range is found out
  // without downloading the whole file.
  Sink sink{&answer.body, body_limit(request)};
  char error_text[CURL_ERROR_SIZE] = {0};
  curl_easy_reset(curl);  // keeps the connection cache
  curl_easy_setopt(curl, CURLOPT_URL, request.url.c_str());
  if (request.ranged) curl_easy_setopt(curl, CURLOPT_RANGE, request.range_text.c_str());
  curl_easy_setopt(curl, CURLOPT_FOLLOWLOCATION, 1L);
  curl_easy_setopt(curl, CURLOPT_MAXREDIRS, 8L);
  curl_easy_setopt(curl, CURLOPT_NOSIGNAL, 1L);  // worker threads: no SIGALRM for timeouts
  const FetchOptions& options = request.options;
  curl_easy_setopt(curl, CURLOPT_CONNECTTIMEOUT_MS, options.connect_timeout_ms);
  curl_easy_setopt(curl, CURLOPT_LOW_SPEED_LIMIT, options.low_speed_bytes);
  curl_easy_setopt(curl, CURLOPT_LOW_SPEED_TIME, options.low_speed_time_s);
  curl_easy_setopt(curl, CURLOPT_TIMEOUT_MS, options.total_timeout_ms);
  // Every encoding libcurl decodes, except on ranges: a range is of the stored bytes.
  if (!request.ranged) {
    curl_easy_setopt(curl, CURLOPT_ACCEPT_ENCODING, "");
    curl_easy_setopt(curl, CURLOPT_MAXFILESIZE_LARGE, curl_off_t(options.max_bytes));
  }
  curl_easy_setopt(curl, CURLOPT_WRITEFUNCTION, write_body);
  curl_easy_setopt(curl, CURLOPT_WRITEDATA, &sink);
  curl_easy_setopt(curl, CURLOPT_ERRORBUFFER, error_text);
  curl_easy_setopt(curl, CURLOPT_USERAGENT, "stipple/0.1");
  const CURLcode code = curl_easy_perform(curl);
  curl_easy_getinfo(curl, CURLINFO_RESPONSE_CODE, &answer.status);
  answer.content_type = header(curl, "Content-Type");
  answer.content_range = header(curl, "Content-Range");
  if (sink.overflow || code == CURLE_FILESIZE_EXCEEDED) {
    answer.over_cap = true;
  } else if (code != CURLE_OK) {
    answer.transport_error = error_text[0] ? error_text : curl_easy_strerror(code);
    answer.transient = transient(code);
  }
  return answer;
}

void sleep_ms(long ms) {
  std::this_thread::sleep_for(std::chrono::milliseconds(ms));
}

}  // namespace stipple::io::detail
