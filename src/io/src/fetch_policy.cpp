// io::fetch's rules for HTTP answers, shared by the libcurl and the browser clients
// (fetch_policy.hpp says what they decide).
#include "stipple/io/fetch_policy.hpp"

#include <charconv>
#include <climits>

#include "fetch_detail.hpp"
#include "stipple/core/error.hpp"
#include "stipple/core/log.hpp"

namespace stipple::io {
namespace {

using detail::starts_with_ci;

bool is_blank(char c) {
  return c == ' ' || c == '\t';
}

std::string_view trim(std::string_view s) {
  while (!s.empty() && is_blank(s.front())) s.remove_prefix(1);
  while (!s.empty() && (is_blank(s.back()) || s.back() == '\r' || s.back() == '\n'))
    s.remove_suffix(1);
  return s;
}

// Reads the decimal number at the front of `s` into `value`; false if there is none (or it does
// not fit 64 bits).
bool take_number(std::string_view& s, uint64_t& value) {
  const auto [end, error] = std::from_chars(s.data(), s.data() + s.size(), value);
  if (error != std::errc() || end == s.data()) return false;
  s.remove_prefix(size_t(end - s.data()));
  return true;
}

bool take_char(std::string_view& s, char c) {
  if (s.empty() || s.front() != c) return false;
  s.remove_prefix(1);
  return true;
}

FetchDecision failure(std::string message) {
  return {FetchVerdict::fail, std::move(message)};
}

}  // namespace

HttpRequest http_request(const std::string& uri, const FetchOptions& options) {
  HttpRequest request;
  request.uri = uri;
  request.url = uri.substr(0, uri.find('#'));
  request.options = options;
  request.ranged = parse_range_uri(uri, &request.range);
  if (request.ranged)
    request.range_text =
        fmt::format("{}-{}", request.range.offset, request.range.offset + request.range.size - 1);
  return request;
}

uint64_t body_limit(const HttpRequest& request) {
  return request.ranged ? request.range.size : request.options.max_bytes;
}

std::optional<ContentRange> parse_content_range(std::string_view value) {
  std::string_view s = trim(value);
  if (!starts_with_ci(s, "bytes")) return std::nullopt;
  s.remove_prefix(5);
  if (s.empty() || !is_blank(s.front())) return std::nullopt;
  while (!s.empty() && is_blank(s.front())) s.remove_prefix(1);
  ContentRange range;
  if (!take_number(s, range.first) || !take_char(s, '-') || !take_number(s, range.last) ||
      !take_char(s, '/'))
    return std::nullopt;
  if (!take_char(s, '*') && !take_number(s, range.total)) return std::nullopt;
  // RFC 9110 14.4: invalid when last < first, or when the length is not past the last byte.
  if (!s.empty() || range.last < range.first || (range.total != 0 && range.total <= range.last))
    return std::nullopt;
  return range;
}

FetchDecision decide_fetch(const HttpRequest& request, const HttpAnswer& answer, int attempt) {
  const FetchOptions& options = request.options;
  const long status = answer.status;
  const std::string& uri = request.uri;
  const std::string& url = request.url;
  // Ranges are checked first: a server that ignores them says so on every try.
  if (request.ranged && status >= 200 && status < 300 && status != 206)
    return failure(fmt::format(
        "{}: the server ignores range requests (HTTP {} to a request for bytes {}); COPC and "
        "other ranged reads need a server with byte-range support",
        url, status, request.range_text));
  if (request.ranged && status == 416)
    return failure(fmt::format("{}: bytes {} are past the end of the file (HTTP 416)", url,
                               request.range_text));
  std::string fault;  // what went wrong on this try
  bool retryable = false;
  if (!answer.transport_error.empty()) {
    fault = answer.transport_error;
    retryable = answer.transient;
  } else if (status >= 500 || status == 429 || status == 408) {
    fault = fmt::format("HTTP {}", status);
    retryable = true;
  } else if (status >= 400) {
    return failure(fmt::format("{}: HTTP {}{}", uri, status, status == 404 ? " (not found)" : ""));
  } else if (request.ranged) {
    const auto range = parse_content_range(answer.content_range);
    const uint64_t last = request.range.offset + request.range.size - 1;
    if (answer.over_cap || !range || range->first != request.range.offset || range->last != last ||
        answer.body.size() != request.range.size) {
      const std::string count = answer.over_cap ? fmt::format("more than {}", request.range.size)
                                                : fmt::format("{}", answer.body.size());
      std::string how;
      if (range)
        how = fmt::format(" at {}-{}", range->first, range->last);
      else if (!answer.content_range.empty())
        how = fmt::format(" and an unreadable Content-Range \"{}\"", answer.content_range);
      else if (answer.headers_may_be_hidden)
        how =
            " without a Content-Range (a cross-origin server must expose it: "
            "Access-Control-Expose-Headers: Content-Range)";
      else
        how = " without a Content-Range";
      return failure(
          fmt::format("{}: the server answered bytes {} with {} bytes{}, not the range asked for",
                      url, request.range_text, count, how));
    }
    FetchDecision done{FetchVerdict::done};
    done.total_size = range->total;
    return done;
  } else if (answer.over_cap) {
    return failure(
        fmt::format("{}: response larger than the limit of {} bytes", uri, options.max_bytes));
  } else {
    if (options.reject_html && (starts_with_ci(trim(answer.content_type), "text/html") ||
                                looks_like_html(answer.body.data(), answer.body.size())))
      return failure(fmt::format("{}: the server answered with an HTML page, not tile data", uri));
    return {FetchVerdict::done};
  }
  if (!retryable || attempt >= options.max_retries)
    return failure(fmt::format("{}: {}{}", uri, fault,
                               attempt > 0 ? fmt::format(" (after {} tries)", attempt + 1) : ""));
  FetchDecision retry{FetchVerdict::retry, std::move(fault)};
  // Doubled after every failed try (saturating: `long` is 32 bits in WebAssembly).
  retry.backoff_ms = options.backoff_initial_ms;
  for (int i = 0; i < attempt; ++i)
    retry.backoff_ms = retry.backoff_ms > LONG_MAX / 2 ? LONG_MAX : retry.backoff_ms * 2;
  return retry;
}

std::vector<uint8_t> fetch_http(const HttpRequest& request, const HttpPerform& perform,
                                const std::function<void(long)>& sleep_ms, FetchStats* stats) {
  if (request.ranged && request.range.size > request.options.max_bytes)
    fail("{}: a read of {} bytes is more than the limit of {} bytes", request.uri,
         request.range.size, request.options.max_bytes);
  for (int attempt = 0;; ++attempt) {
    HttpAnswer answer = perform(request);
    if (stats) {
      stats->attempts = attempt + 1;
      stats->http_status = answer.status;
    }
    FetchDecision decision = decide_fetch(request, answer, attempt);
    switch (decision.verdict) {
      case FetchVerdict::done:
        if (stats && request.ranged) stats->total_size = decision.total_size;
        return std::move(answer.body);
      case FetchVerdict::fail:
        throw Error(decision.message);
      case FetchVerdict::retry:
        STIPPLE_DEBUG("{}: {}; retrying in {} ms", request.uri, decision.message,
                      decision.backoff_ms);
        sleep_ms(decision.backoff_ms);
        break;
    }
  }
}

}  // namespace stipple::io
