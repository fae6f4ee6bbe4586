#pragma once
// The rules io::fetch applies to an http(s) URL, apart from the client that makes the requests
// (libcurl natively, the browser's fetch() or XMLHttpRequest in the web build). A client performs
// one request and reports what came back as it is (an HttpAnswer: status, raw headers, bytes, or
// why there was no answer); decide_fetch says whether that is the body, a fault worth another try
// (after a back-off) or an error, checking the range answered, the size cap and that no HTML page
// came where data was expected; fetch_http is the loop of tries. Both builds share them, so they
// answer alike, and they are tested without a server.
#include <cstdint>
#include <functional>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "stipple/io/fetch.hpp"

namespace stipple::io {

// One http(s) read of io::fetch.
struct HttpRequest {
  std::string uri;  // as given: messages name it
  std::string url;  // what is requested: the URI without its fragment (ours, never sent)
  bool ranged = false;
  ByteRange range;
  std::string range_text;  // ranged: "FIRST-LAST", the Range header's value after "bytes="
  FetchOptions options;
};
HttpRequest http_request(const std::string& uri, const FetchOptions& options);

// The most body bytes a client keeps: the range's size, else options.max_bytes. Past it a client
// stops reading (or drops what the browser already has) and sets HttpAnswer::over_cap, so a
// server ignoring a range is found out without downloading the whole file.
uint64_t body_limit(const HttpRequest& request);

// What one request got, as the client saw it.
struct HttpAnswer {
  // No HTTP answer, or one cut off (refused, unresolved, reset, timed out): the client's words,
  // and whether another try may succeed. Empty when the answer is complete (or over the cap).
  std::string transport_error;
  bool transient = false;
  long status = 0;  // 0: none
  // The headers' values as sent; empty when absent.
  std::string content_type;
  std::string content_range;
  std::vector<uint8_t> body;
  bool over_cap = false;  // the body passed body_limit(): `body` is cut short or empty
  // The browser hides the headers a cross-origin server does not expose (CORS): a missing
  // Content-Range may be hidden rather than absent, and the message says how to expose it.
  bool headers_may_be_hidden = false;
};

// A Content-Range value "bytes FIRST-LAST/TOTAL" (TOTAL may be "*": 0, unknown); nullopt for
// anything else, "bytes */TOTAL" (no range) included.
struct ContentRange {
  uint64_t first = 0, last = 0, total = 0;
};
std::optional<ContentRange> parse_content_range(std::string_view value);

enum class FetchVerdict { done, retry, fail };
struct FetchDecision {
  FetchVerdict verdict = FetchVerdict::fail;
  // fail: the error, naming the URI; retry: the fault, for the log.
  std::string message;
  long backoff_ms = 0;      // retry: the wait before the next try
  uint64_t total_size = 0;  // done, ranged: the whole file's size (Content-Range; 0: unknown)
};

// Decides on `answer`, the result of try `attempt` (0: the first) of `request`. Retried, while
// options.max_retries allows, after backoff_initial_ms doubled per try: no answer where the
// client says it is transient, HTTP 5xx, 429 and 408. An error: other missing answers, other
// 4xx, a 2xx other than 206 to a range (the server ignores ranges), 416 to a range, a body over
// the cap, a 206 whose Content-Range or size is not the range asked for, an HTML page (by
// Content-Type or content) where data was expected (options.reject_html).
FetchDecision decide_fetch(const HttpRequest& request, const HttpAnswer& answer, int attempt);

// The tries of `request`: `perform` makes one and reports it, `sleep_ms` waits out a back-off.
// Returns the body or throws stipple::Error with decide_fetch's message; `stats` (if given) has
// the tries made, the last status and a range's total size.
using HttpPerform = std::function<HttpAnswer(const HttpRequest&)>;
std::vector<uint8_t> fetch_http(const HttpRequest& request, const HttpPerform& perform,
                                const std::function<void(long)>& sleep_ms,
                                FetchStats* stats = nullptr);

}  // namespace stipple::io
