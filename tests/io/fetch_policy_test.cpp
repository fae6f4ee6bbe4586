// io::fetch's rules for HTTP answers (fetch_policy.hpp), without a server: decide_fetch on
// answers made up as a client would report them (statuses, a wrong or missing Content-Range, an
// HTML page, the size cap, network errors transient or not), and the loop of tries (fetch_http)
// with a scripted client: its retries, back-offs and stats.
#include "stipple/io/fetch_policy.hpp"

#include <climits>
#include <deque>

#include <gtest/gtest.h>

#include "stipple/core/error.hpp"

using namespace stipple;
using namespace stipple::io;

namespace {

const std::string kUrl = "http://h/a/data.bin";

HttpRequest plain_request(FetchOptions options = {}) {
  return http_request(kUrl, options);
}

// Bytes 100-149 of the file.
HttpRequest ranged_request(FetchOptions options = {}) {
  return http_request(range_uri(kUrl, 100, 50) + "&points=3", options);
}

HttpAnswer answer(long status, size_t size = 10, std::string content_range = {}) {
  HttpAnswer a;
  a.status = status;
  a.body.assign(size, uint8_t('x'));
  a.content_range = std::move(content_range);
  return a;
}

HttpAnswer no_answer(std::string why, bool transient) {
  HttpAnswer a;
  a.transport_error = std::move(why);
  a.transient = transient;
  return a;
}

bool has(const std::string& text, const std::string& part) {
  return text.find(part) != std::string::npos;
}

}  // namespace

TEST(FetchPolicy, RequestsAreTheUriWithoutItsFragment) {
  const HttpRequest plain = plain_request();
  EXPECT_EQ(plain.url, kUrl);
  EXPECT_FALSE(plain.ranged);
  EXPECT_EQ(body_limit(plain), FetchOptions{}.max_bytes);
  const HttpRequest ranged = ranged_request();
  EXPECT_EQ(ranged.url, kUrl);
  EXPECT_TRUE(ranged.ranged);
  EXPECT_EQ(ranged.range.offset, 100u);
  EXPECT_EQ(ranged.range.size, 50u);
  EXPECT_EQ(ranged.range_text, "100-149");
  EXPECT_EQ(body_limit(ranged), 50u);
}

TEST(FetchPolicy, ContentRangeIsParsedStrictly) {
  auto r = parse_content_range("bytes 100-149/1000");
  ASSERT_TRUE(r);
  EXPECT_EQ(r->first, 100u);
  EXPECT_EQ(r->last, 149u);
  EXPECT_EQ(r->total, 1000u);
  r = parse_content_range("  Bytes   0-0/*\r\n");
  ASSERT_TRUE(r);
  EXPECT_EQ(r->first, 0u);
  EXPECT_EQ(r->last, 0u);
  EXPECT_EQ(r->total, 0u);  // unknown
  r = parse_content_range("bytes 0-18446744073709551614/18446744073709551615");
  ASSERT_TRUE(r);
  EXPECT_EQ(r->last, 18446744073709551614ull);
  for (const char* bad :
       {"", "bytes", "bytes */1000", "bytes 5-4/1000", "bytes 0-999/1000x", "bytes 0-1000/1000",
        "bytes 0-1/", "bytes -1-5/10", "bytes 1-/10", "bytes1-2/10", "items 1-2/10",
        "bytes 0-18446744073709551616/*", "bytes 1 - 2/10"})
    EXPECT_FALSE(parse_content_range(bad)) << bad;
}

TEST(FetchPolicy, OkIsTheBody) {
  const FetchDecision d = decide_fetch(plain_request(), answer(200), 0);
  EXPECT_EQ(d.verdict, FetchVerdict::done);
}

TEST(FetchPolicy, RangeAnsweredWithTheRangeIsTheBody) {
  const FetchDecision d = decide_fetch(ranged_request(), answer(206, 50, "bytes 100-149/1000"), 0);
  EXPECT_EQ(d.verdict, FetchVerdict::done) << d.message;
  EXPECT_EQ(d.total_size, 1000u);
  const FetchDecision unknown =
      decide_fetch(ranged_request(), answer(206, 50, "bytes 100-149/*"), 0);
  EXPECT_EQ(unknown.verdict, FetchVerdict::done) << unknown.message;
  EXPECT_EQ(unknown.total_size, 0u);
}

TEST(FetchPolicy, ARangeAnsweredWithAnythingElseFails) {
  const HttpRequest request = ranged_request();
  auto fails_with = [&](const HttpAnswer& a, const std::string& part) {
    const FetchDecision d = decide_fetch(request, a, 0);
    EXPECT_EQ(d.verdict, FetchVerdict::fail) << part;
    EXPECT_TRUE(has(d.message, part)) << d.message;
    EXPECT_TRUE(has(d.message, kUrl + ": ")) << d.message;
    EXPECT_FALSE(has(d.message, "#bytes")) << "names the URL sent: " << d.message;
  };
  fails_with(answer(200, 50),
             "the server ignores range requests (HTTP 200 to a request for bytes "
             "100-149); COPC and other ranged reads need a server with "
             "byte-range support");
  fails_with(answer(204, 0), "ignores range requests (HTTP 204");
  fails_with(answer(416, 0), "bytes 100-149 are past the end of the file (HTTP 416)");
  fails_with(answer(206, 50, "bytes 0-49/1000"),
             "the server answered bytes 100-149 with 50 bytes at 0-49, not the range asked for");
  fails_with(answer(206, 60, "bytes 100-159/1000"), "with 60 bytes at 100-159, not the range");
  fails_with(answer(206, 40, "bytes 100-149/1000"), "with 40 bytes at 100-149, not the range");
  fails_with(answer(206, 50), "with 50 bytes without a Content-Range, not the range asked for");
  fails_with(answer(206, 50, "bytes */1000"),
             "with 50 bytes and an unreadable Content-Range \"bytes */1000\", not the range");
  // A body longer than the range is cut at its size.
  HttpAnswer longer = answer(206, 50, "bytes 100-199/1000");
  longer.over_cap = true;
  fails_with(longer, "with more than 50 bytes at 100-199, not the range asked for");
  // In the browser a Content-Range may be hidden (CORS): the message says how to expose it.
  HttpAnswer hidden = answer(206, 50);
  hidden.headers_may_be_hidden = true;
  fails_with(hidden,
             "without a Content-Range (a cross-origin server must expose it: "
             "Access-Control-Expose-Headers: Content-Range)");
  // A range that is ignored is not retried even where the transfer was cut off.
  HttpAnswer cut = answer(200, 20);
  cut.transport_error = "Recv failure";
  cut.transient = true;
  fails_with(cut, "ignores range requests");
}

TEST(FetchPolicy, ClientErrorsFailAtOnce) {
  const FetchDecision missing = decide_fetch(plain_request(), answer(404), 0);
  EXPECT_EQ(missing.verdict, FetchVerdict::fail);
  EXPECT_EQ(missing.message, kUrl + ": HTTP 404 (not found)");
  const FetchDecision forbidden = decide_fetch(plain_request(), answer(403), 0);
  EXPECT_EQ(forbidden.verdict, FetchVerdict::fail);
  EXPECT_EQ(forbidden.message, kUrl + ": HTTP 403");
  // Ranged: the URI as given.
  const FetchDecision ranged = decide_fetch(ranged_request(), answer(404), 0);
  EXPECT_EQ(ranged.verdict, FetchVerdict::fail);
  EXPECT_EQ(ranged.message, range_uri(kUrl, 100, 50) + "&points=3: HTTP 404 (not found)");
}

TEST(FetchPolicy, ServerFaultsAreRetriedWithBackoffThenFail) {
  FetchOptions options;
  options.max_retries = 3;
  options.backoff_initial_ms = 100;
  for (long status : {500L, 503L, 429L, 408L, 502L}) {
    for (const HttpRequest& request : {plain_request(options), ranged_request(options)}) {
      for (int attempt = 0; attempt < 3; ++attempt) {
        const FetchDecision d = decide_fetch(request, answer(status), attempt);
        EXPECT_EQ(d.verdict, FetchVerdict::retry) << status << " try " << attempt;
        EXPECT_EQ(d.message, fmt::format("HTTP {}", status));
        EXPECT_EQ(d.backoff_ms, 100L << attempt);
      }
      const FetchDecision last = decide_fetch(request, answer(status), 3);
      EXPECT_EQ(last.verdict, FetchVerdict::fail);
      EXPECT_EQ(last.message, fmt::format("{}: HTTP {} (after 4 tries)", request.uri, status));
    }
  }
  options.max_retries = 0;
  const FetchDecision once = decide_fetch(plain_request(options), answer(503), 0);
  EXPECT_EQ(once.verdict, FetchVerdict::fail);
  EXPECT_EQ(once.message, kUrl + ": HTTP 503");
}

TEST(FetchPolicy, BackoffSaturates) {
  FetchOptions options;
  options.max_retries = 1000;
  options.backoff_initial_ms = 1000;
  const FetchDecision d = decide_fetch(plain_request(options), answer(503), 100);
  EXPECT_EQ(d.verdict, FetchVerdict::retry);
  EXPECT_EQ(d.backoff_ms, LONG_MAX);
}

TEST(FetchPolicy, NetworkErrorsAreRetriedWhereTransient) {
  FetchOptions options;
  options.max_retries = 2;
  const HttpRequest request = plain_request(options);
  const FetchDecision reset = decide_fetch(request, no_answer("Connection reset", true), 0);
  EXPECT_EQ(reset.verdict, FetchVerdict::retry);
  EXPECT_EQ(reset.message, "Connection reset");
  EXPECT_EQ(reset.backoff_ms, options.backoff_initial_ms);
  const FetchDecision given_up = decide_fetch(request, no_answer("Connection reset", true), 2);
  EXPECT_EQ(given_up.verdict, FetchVerdict::fail);
  EXPECT_EQ(given_up.message, kUrl + ": Connection reset (after 3 tries)");
  const FetchDecision bad = decide_fetch(request, no_answer("Unsupported protocol", false), 0);
  EXPECT_EQ(bad.verdict, FetchVerdict::fail);
  EXPECT_EQ(bad.message, kUrl + ": Unsupported protocol");
  // A transfer cut off after a good status is a network error too.
  HttpAnswer cut = answer(200, 5);
  cut.transport_error = "transfer closed with 5 bytes remaining to read";
  cut.transient = true;
  EXPECT_EQ(decide_fetch(request, cut, 0).verdict, FetchVerdict::retry);
}

TEST(FetchPolicy, HtmlWhereDataWasExpectedFails) {
  const std::string message = kUrl + ": the server answered with an HTML page, not tile data";
  HttpAnswer typed = answer(200);
  typed.content_type = "Text/HTML; charset=utf-8";
  FetchDecision d = decide_fetch(plain_request(), typed, 0);
  EXPECT_EQ(d.verdict, FetchVerdict::fail);
  EXPECT_EQ(d.message, message);
  HttpAnswer page;
  page.status = 200;
  page.content_type = "application/octet-stream";
  const std::string html = "\xEF\xBB\xBF  \n<!DOCTYPE html><html><body>login</body></html>";
  page.body.assign(html.begin(), html.end());
  d = decide_fetch(plain_request(), page, 0);
  EXPECT_EQ(d.verdict, FetchVerdict::fail);
  EXPECT_EQ(d.message, message);
  // Allowed where HTML is wanted.
  FetchOptions options;
  options.reject_html = false;
  EXPECT_EQ(decide_fetch(plain_request(options), page, 0).verdict, FetchVerdict::done);
  EXPECT_EQ(decide_fetch(plain_request(options), typed, 0).verdict, FetchVerdict::done);
  // Data that merely mentions HTML is data.
  HttpAnswer data = answer(200);
  data.content_type = "application/json";
  const std::string json = "{\"html\": \"<html>\"}";
  data.body.assign(json.begin(), json.end());
  EXPECT_EQ(decide_fetch(plain_request(), data, 0).verdict, FetchVerdict::done);
}

TEST(FetchPolicy, ABodyOverTheCapFails) {
  FetchOptions options;
  options.max_bytes = 1000;
  HttpAnswer big = answer(200, 1000);
  big.over_cap = true;
  const FetchDecision d = decide_fetch(plain_request(options), big, 0);
  EXPECT_EQ(d.verdict, FetchVerdict::fail);
  EXPECT_EQ(d.message, kUrl + ": response larger than the limit of 1000 bytes");
  // An error status over the cap is that error: a large error page is still a 404 or a 503.
  HttpAnswer missing = answer(404, 0);
  missing.over_cap = true;
  EXPECT_EQ(decide_fetch(plain_request(options), missing, 0).message,
            kUrl + ": HTTP 404 (not found)");
  HttpAnswer busy = answer(503, 0);
  busy.over_cap = true;
  EXPECT_EQ(decide_fetch(plain_request(options), busy, 0).verdict, FetchVerdict::retry);
}

TEST(FetchPolicy, TheLoopRetriesSleepsAndCounts) {
  FetchOptions options;
  options.max_retries = 4;
  options.backoff_initial_ms = 50;
  std::deque<HttpAnswer> script = {answer(503), no_answer("Connection refused", true),
                                   answer(206, 50, "bytes 100-149/4096")};
  std::vector<long> sleeps;
  int tries = 0;
  FetchStats stats;
  const auto body = fetch_http(
      ranged_request(options),
      [&](const HttpRequest& request) {
        EXPECT_EQ(request.range_text, "100-149");
        ++tries;
        HttpAnswer a = std::move(script.front());
        script.pop_front();
        return a;
      },
      [&](long ms) { sleeps.push_back(ms); }, &stats);
  EXPECT_EQ(body.size(), 50u);
  EXPECT_EQ(tries, 3);
  EXPECT_EQ(sleeps, (std::vector<long>{50, 100}));
  EXPECT_EQ(stats.attempts, 3);
  EXPECT_EQ(stats.http_status, 206);
  EXPECT_EQ(stats.total_size, 4096u);
}

TEST(FetchPolicy, TheLoopStopsAtTheFirstError) {
  FetchOptions options;
  options.max_retries = 4;
  std::deque<HttpAnswer> script = {answer(500), answer(404), answer(200)};
  std::vector<long> sleeps;
  FetchStats stats;
  try {
    fetch_http(
        plain_request(options),
        [&](const HttpRequest&) {
          HttpAnswer a = std::move(script.front());
          script.pop_front();
          return a;
        },
        [&](long ms) { sleeps.push_back(ms); }, &stats);
    ADD_FAILURE() << "a 404 was not an error";
  } catch (const Error& e) {
    EXPECT_EQ(std::string(e.what()), kUrl + ": HTTP 404 (not found)");
  }
  EXPECT_EQ(script.size(), 1u);
  EXPECT_EQ(sleeps.size(), 1u);
  EXPECT_EQ(stats.attempts, 2);
  EXPECT_EQ(stats.http_status, 404);
}

TEST(FetchPolicy, ARangeOverTheCapIsNotRequested) {
  FetchOptions options;
  options.max_bytes = 10;
  int tries = 0;
  try {
    fetch_http(
        ranged_request(options),
        [&](const HttpRequest&) {
          ++tries;
          return answer(206, 50, "bytes 100-149/1000");
        },
        [](long) {});
    ADD_FAILURE() << "a range over the cap was read";
  } catch (const Error& e) {
    EXPECT_TRUE(has(e.what(), "a read of 50 bytes is more than the limit of 10 bytes")) << e.what();
  }
  EXPECT_EQ(tries, 0);
}
