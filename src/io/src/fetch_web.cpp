// io::fetch's HTTP client in the web build: the browser. A synchronous XMLHttpRequest on worker
// threads (the streamer's pool; blocking a worker stalls no page), and fetch() awaited through
// JSPI on the main thread (its wasm stack is suspended while the page runs on). Each performs
// one request and reports it (perform_http); retries, back-off, the range, size and HTML checks
// are fetch_policy.cpp's, the same as the libcurl client's. Local paths are files of
// emscripten's in-memory file system (fetch_common.cpp).
#include <emscripten.h>
#include <emscripten/threading.h>

#include <chrono>
#include <string>
#include <thread>
#include <vector>

#include "fetch_detail.hpp"
#include "stipple/core/error.hpp"

// (No backslashes or empty '' literals in the JS below: it is a C++ macro argument, stringified.)
// Both requests leave the body in globalThis.stippleBodies (per thread: each worker has its own
// globals) under the id they return (0: no answer, the reason in `error`); stipple_http_take
// copies it into wasm memory and forgets it. They write the HTTP status, the body's size and the
// Content-Type and Content-Range headers as sent (empty where absent or not exposed by CORS).
// clang-format off
EM_JS(int, stipple_http_sync, (const char* url, const char* range, int* status, double* size,
                               char* type, int type_size, char* content_range, int range_size,
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
  HEAP32[status >> 2] = xhr.status;
  HEAPF64[size >> 3] = body.length;
  stringToUTF8(xhr.getResponseHeader("Content-Type") || "", type, type_size);
  stringToUTF8(xhr.getResponseHeader("Content-Range") || "", content_range, range_size);
  globalThis.stippleBodies = globalThis.stippleBodies || new Map();
  globalThis.stippleNextBody = (globalThis.stippleNextBody || 0) + 1;
  globalThis.stippleBodies.set(globalThis.stippleNextBody, body);
  return globalThis.stippleNextBody;
});

EM_ASYNC_JS(int, stipple_http_async, (const char* url, const char* range, int* status,
                                      double* size, char* type, int type_size,
                                      char* content_range, int range_size, char* error,
                                      int error_size), {
  const r = UTF8ToString(range);
  let response, body;
  try {
    response = await fetch(UTF8ToString(url), r ? {headers: {Range: 'bytes=' + r}} : {});
    body = new Uint8Array(await response.arrayBuffer());
  } catch (e) {
    stringToUTF8(String((e && e.message) || e), error, error_size);
    return 0;
  }
  HEAP32[status >> 2] = response.status;
  HEAPF64[size >> 3] = body.length;
  stringToUTF8(response.headers.get("Content-Type") || "", type, type_size);
  stringToUTF8(response.headers.get("Content-Range") || "", content_range, range_size);
  globalThis.stippleBodies = globalThis.stippleBodies || new Map();
  globalThis.stippleNextBody = (globalThis.stippleNextBody || 0) + 1;
  globalThis.stippleBodies.set(globalThis.stippleNextBody, body);
  return globalThis.stippleNextBody;
});

// Copies body `id` to `out` (unless null) and forgets it.
EM_JS(void, stipple_http_take, (int id, uint8_t* out), {
  const body = globalThis.stippleBodies.get(id);
  globalThis.stippleBodies.delete(id);
  if (out && body) HEAPU8.set(body, out >>> 0);  // above 2 GiB: unsigned
});

EM_ASYNC_JS(void, stipple_sleep_async, (double ms), {
  await new Promise((resolve) => setTimeout(resolve, ms));
});
// clang-format on

namespace stipple::io::detail {

HttpAnswer perform_http(const HttpRequest& request) {
  // Only the main thread may wait for a promise (JSPI); workers may block on a request.
  const bool main_thread = emscripten_is_main_browser_thread();
  int status = 0;
  double size = 0;
  // Enough for any Content-Range; a longer Content-Type is cut, past the part that is checked.
  char type[256] = {0}, content_range[128] = {0}, error[512] = {0};
  const int id = main_thread
                     ? stipple_http_async(request.url.c_str(), request.range_text.c_str(), &status,
                                          &size, type, int(sizeof type), content_range,
                                          int(sizeof content_range), error, int(sizeof error))
                     : stipple_http_sync(request.url.c_str(), request.range_text.c_str(), &status,
                                         &size, type, int(sizeof type), content_range,
                                         int(sizeof content_range), error, int(sizeof error));
  HttpAnswer answer;
  answer.headers_may_be_hidden = true;
  if (id == 0) {
    // The browser does not say why (by design): no server, a refused connection, or a
    // cross-origin server that does not allow this page (CORS).
    answer.transport_error = fmt::format(
        "{} (the server cannot be reached, or it does not allow this page's origin: CORS)",
        error[0] ? error : "network error");
    answer.transient = true;
    return answer;
  }
  answer.status = status;
  answer.content_type = type;
  answer.content_range = content_range;
  // A body over the cap is not copied (the browser has it already: it cannot be stopped).
  answer.over_cap = uint64_t(size) > body_limit(request);
  if (!answer.over_cap) answer.body.resize(size_t(size));
  stipple_http_take(id, answer.over_cap ? nullptr : answer.body.data());
  return answer;
}

void sleep_ms(long ms) {
  if (emscripten_is_main_browser_thread())
    stipple_sleep_async(double(ms));
  else
    std::this_thread::sleep_for(std::chrono::milliseconds(ms));
}

}  // namespace stipple::io::detail
