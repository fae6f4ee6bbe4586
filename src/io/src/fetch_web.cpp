// io::fetch in the browser (the web build). http(s) URLs go through the browser: a synchronous
// XMLHttpRequest on worker threads (the streamer's pool; blocking a worker stalls no page), and
// fetch() awaited through JSPI on the main thread (its wasm stack is suspended while the page
// runs on). The same limits and answers as the libcurl client: retries with back-off on 5xx,
// 429, 408 and network errors, never on 4xx; ranges must be answered with 206 and the range
// asked for; an HTML page where data was expected is an error; a size cap per response. Local
// paths are files of emscripten's in-memory file system.
#include <emscripten.h>
#include <emscripten/threading.h>

#include <chrono>
#include <string>
#include <thread>
#include <vector>

#include "fetch_detail.hpp"
#include "stipple/core/error.hpp"
#include "stipple/core/log.hpp"
#include "stipple/io/fetch.hpp"

// (No backslashes or empty '' literals in the JS below: it is a C++ macro argument, stringified.)
// Both requests leave the body in globalThis.stippleBodies (per thread: each worker has its own
// globals) under the id they return (0: no answer, the reason in `error`); stipple_http_take
// copies it into wasm memory and forgets it. info: HTTP status, whether the Content-Type is
// HTML; numbers: body size, Content-Range first, last and total (-1 where absent).
// clang-format off
EM_JS(int, stipple_http_sync, (const char* url, const char* range, int* info, double* numbers,
                               char* error, int error_size), {
  const r = UTF8ToString(range);
  const xhr = new XMLHttpRequest();
  try {
    xhr.open('GET', UTF8ToString(url), false);
    xhr.responseType = 'arraybuffer';
    if (r) xhr.setRequestHeader('Range', 'bytes=' + r);
    xhr.send();
  } catch (e) {
    stringToUTF8(String((e && e.message) || e), error, error_size);
    return 0;
  }
  if (xhr.status === 0) {
    stringToUTF8('network error', error, error_size);
    return 0;
  }
  const body = new Uint8Array(xhr.response || new ArrayBuffer(0));
  const type = xhr.getResponseHeader("Content-Type") || "";
  const range_text = (xhr.getResponseHeader("Content-Range") || "").trim();
  HEAP32[info >> 2] = xhr.status;
  HEAP32[(info >> 2) + 1] = type.toLowerCase().startsWith("text/html") ? 1 : 0;
  let first = -1, last = -1, total = -1;
  if (range_text.startsWith("bytes ")) {
    const [span, all] = range_text.slice(6).split("/");
    const [a, b] = (span || "").split("-");
    first = Number(a);
    last = Number(b);
    total = all === "*" ? -1 : Number(all);
  }
  HEAPF64[numbers >> 3] = body.length;
  HEAPF64[(numbers >> 3) + 1] = first >= 0 && last >= first ? first : -1;
  HEAPF64[(numbers >> 3) + 2] = first >= 0 && last >= first ? last : -1;
  HEAPF64[(numbers >> 3) + 3] = total >= 0 ? total : -1;
  globalThis.stippleBodies = globalThis.stippleBodies || new Map();
  globalThis.stippleNextBody = (globalThis.stippleNextBody || 0) + 1;
  globalThis.stippleBodies.set(globalThis.stippleNextBody, body);
  return globalThis.stippleNextBody;
});

EM_ASYNC_JS(int, stipple_http_async, (const char* url, const char* range, int* info,
                                      double* numbers, char* error, int error_size), {
  const r = UTF8ToString(range);
  let response, body;
  try {
    response = await fetch(UTF8ToString(url), r ? {headers: {Range: 'bytes=' + r}} : {});
    body = new Uint8Array(await response.arrayBuffer());
  } catch (e) {
    stringToUTF8(String((e && e.message) || e), error, error_size);
    return 0;
  }
  const type = response.headers.get("Content-Type") || "";
  const range_text = (response.headers.get("Content-Range") || "").trim();
  HEAP32[info >> 2] = response.status;
  HEAP32[(info >> 2) + 1] = type.toLowerCase().startsWith("text/html") ? 1 : 0;
  let first = -1, last = -1, total = -1;
  if (range_text.startsWith("bytes ")) {
    const [span, all] = range_text.slice(6).split("/");
    const [a, b] = (span || "").split("-");
    first = Number(a);
    last = Number(b);
    total = all === "*" ? -1 : Number(all);
  }
  HEAPF64[numbers >> 3] = body.length;
  HEAPF64[(numbers >> 3) + 1] = first >= 0 && last >= first ? first : -1;
  HEAPF64[(numbers >> 3) + 2] = first >= 0 && last >= first ? last : -1;
  HEAPF64[(numbers >> 3) + 3] = total >= 0 ? total : -1;
  globalThis.stippleBodies = globalThis.stippleBodies || new Map();
  globalThis.stippleNextBody = (globalThis.stippleNextBody || 0) + 1;
  globalThis.stippleBodies.set(globalThis.stippleNextBody, body);
  return globalThis.stippleNextBody;
});

// Copies body `id` to `out` (unless null) and forgets it.
EM_JS(void, stipple_http_take, (int id, uint8_t* out), {
  const body = globalThis.stippleBodies.get(id);
  globalThis.stippleBodies.delete(id);
  if (out && body) HEAPU8.set(body, out);
});

EM_ASYNC_JS(void, stipple_sleep_async, (double ms), {
  await new Promise((resolve) => setTimeout(resolve, ms));
});
// clang-format on

namespace stipple::io {

std::vector<uint8_t> fetch(const std::string& uri, const FetchOptions& options, FetchStats* stats) {
  ByteRange range;
  const bool ranged = parse_range_uri(uri, &range);
  if (!is_url(uri)) {
    if (ranged) return detail::read_file_range(uri, range, options, stats);
    if (stats) stats->attempts = 1;
    return detail::read_file(uri.substr(0, uri.find('#')), options);  // fields after '#' are ours
  }
  if (ranged && range.size > options.max_bytes)
    fail("{}: a read of {} bytes is more than the limit of {} bytes", uri, range.size,
         options.max_bytes);
  // The fragment is ours (a range, fields): servers never see it.
  const std::string url = uri.substr(0, uri.find('#'));
  const std::string range_text =
      ranged ? fmt::format("{}-{}", range.offset, range.offset + range.size - 1) : "";
  // Only the main thread may wait for a promise (JSPI); workers may block on a request.
  const bool main_thread = emscripten_is_main_browser_thread();
  long backoff = options.backoff_initial_ms;
  for (int attempt = 0;; ++attempt) {
    int info[2] = {0, 0};
    double numbers[4] = {0, -1, -1, -1};
    char error[512] = {0};
    const int id = main_thread ? stipple_http_async(url.c_str(), range_text.c_str(), info, numbers,
                                                    error, int(sizeof error))
                               : stipple_http_sync(url.c_str(), range_text.c_str(), info, numbers,
                                                   error, int(sizeof error));
    const long status = info[0];
    const uint64_t size = uint64_t(numbers[0]);
    std::vector<uint8_t> body;
    if (id > 0) {
      // A body over the cap is not copied (the browser has it already: it cannot be stopped).
      const bool keep = size <= (ranged ? range.size : options.max_bytes);
      if (keep) body.resize(size);
      stipple_http_take(id, keep ? body.data() : nullptr);
    }
    if (stats) {
      stats->attempts = attempt + 1;
      stats->http_status = status;
    }
    std::string problem;
    bool retry = false;
    if (id == 0) {
      // The browser does not say why (by design): no server, a refused connection, or a
      // cross-origin server that does not allow this page (CORS).
      problem = fmt::format(
          "{} (the server cannot be reached, or it does not allow this page's origin: CORS)",
          error[0] ? error : "network error");
      retry = true;
    } else if (ranged && status >= 200 && status < 300 && status != 206) {
      fail(
          "{}: the server ignores range requests (HTTP {} to a request for bytes {}); COPC and "
          "other ranged reads need a server with byte-range support",
          url, status, range_text);
    } else if (ranged && status == 416) {
      fail("{}: bytes {} are past the end of the file (HTTP 416)", url, range_text);
    } else if (status >= 500 || status == 429 || status == 408) {
      problem = fmt::format("HTTP {}", status);
      retry = true;
    } else if (status >= 400) {
      fail("{}: HTTP {}{}", uri, status, status == 404 ? " (not found)" : "");
    } else if (!ranged && size > options.max_bytes) {
      fail("{}: response larger than the limit of {} bytes", uri, options.max_bytes);
    } else if (ranged) {
      if (numbers[1] < 0)
        fail(
            "{}: the server answered bytes {} without a Content-Range header (a cross-origin "
            "server must expose it: Access-Control-Expose-Headers: Content-Range)",
            url, range_text);
      if (uint64_t(numbers[1]) != range.offset || size != range.size)
        fail("{}: the server answered bytes {} with {} bytes at {}-{}, not the range asked for",
             url, range_text, size, uint64_t(numbers[1]), uint64_t(numbers[2]));
      if (stats) stats->total_size = numbers[3] < 0 ? 0 : uint64_t(numbers[3]);
      return body;
    } else {
      if (options.reject_html && (info[1] || looks_like_html(body.data(), body.size())))
        fail("{}: the server answered with an HTML page, not tile data", uri);
      return body;
    }
    if (!retry || attempt >= options.max_retries)
      fail("{}: {}{}", uri, problem,
           attempt > 0 ? fmt::format(" (after {} tries)", attempt + 1) : "");
    STIPPLE_DEBUG("{}: {}; retrying in {} ms", uri, problem, backoff);
    if (main_thread)
      stipple_sleep_async(double(backoff));
    else
      std::this_thread::sleep_for(std::chrono::milliseconds(backoff));
    backoff *= 2;
  }
}

}  // namespace stipple::io
