#pragma once
// Logging and assertion macros over spdlog; everything logs to stderr so stdout stays for data.
#include <spdlog/spdlog.h>

namespace stipple {
// verbosity: 0 warnings and errors, 1 info, 2 debug, 3 trace.
void init_logging(int verbosity);
[[noreturn]] void assert_failed(const char* expr, const char* file, int line, const char* message);
}  // namespace stipple

#define STIPPLE_TRACE(...) SPDLOG_TRACE(__VA_ARGS__)
#define STIPPLE_DEBUG(...) spdlog::debug(__VA_ARGS__)
#define STIPPLE_INFO(...) spdlog::info(__VA_ARGS__)
#define STIPPLE_WARN(...) spdlog::warn(__VA_ARGS__)
#define STIPPLE_ERROR(...) spdlog::error(__VA_ARGS__)
// Invariant checks stay on in release builds: a broken invariant must never produce output.
#define STIPPLE_ASSERT(expr, message)                                          \
  do {                                                                         \
    if (!(expr)) ::stipple::assert_failed(#expr, __FILE__, __LINE__, message); \
  } while (false)
