#pragma once
// Logging and assertion macros over spdlog; everything logs to stderr so stdout stays for data.
#include <string>

#include <spdlog/spdlog.h>

namespace stipple {
// verbosity: 0 warnings and errors, 1 info, 2 debug, 3 trace.
void init_logging(int verbosity);
[[noreturn]] void assert_failed(const char* expr, const char* file, int line, const char* message);
// Logs a warning unless the same text was logged this way before in this process: facts about
// an input that every reader of it finds again (a command may parse a LAS header several
// times) are said once.
void warn_once(const std::string& message);
}  // namespace stipple

#define STIPPLE_TRACE(...) SPDLOG_TRACE(__VA_ARGS__)
#define STIPPLE_DEBUG(...) spdlog::debug(__VA_ARGS__)
#define STIPPLE_INFO(...) spdlog::info(__VA_ARGS__)
#define STIPPLE_WARN(...) spdlog::warn(__VA_ARGS__)
#define STIPPLE_WARN_ONCE(...) ::stipple::warn_once(fmt::format(__VA_ARGS__))
#define STIPPLE_ERROR(...) spdlog::error(__VA_ARGS__)
// Invariant checks stay on in release builds: a broken invariant must never produce output.
#define STIPPLE_ASSERT(expr, message)                                          \
  do {                                                                         \
    if (!(expr)) ::stipple::assert_failed(#expr, __FILE__, __LINE__, message); \
  } while (false)
