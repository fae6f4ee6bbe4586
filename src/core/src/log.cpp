#include "stipple/core/log.hpp"

#include <cstdlib>
#include <mutex>
#include <string>
#include <unordered_set>

#include <spdlog/sinks/stdout_color_sinks.h>

namespace stipple {

void init_logging(int verbosity) {
  static auto logger = [] {
    auto l = spdlog::stderr_color_mt("stipple");
    spdlog::set_default_logger(l);
    spdlog::set_pattern("%^[%l]%$ %v");
    return l;
  }();
  constexpr spdlog::level::level_enum levels[] = {spdlog::level::warn, spdlog::level::info,
                                                  spdlog::level::debug, spdlog::level::trace};
  logger->set_level(levels[verbosity < 0 ? 0 : verbosity > 3 ? 3 : verbosity]);
}

void warn_once(const std::string& message) {
  // Nothing is remembered while warnings are not shown (a fuzzer, a quiet library user): the
  // set would grow with every distinct message, for nothing.
  if (!spdlog::default_logger_raw()->should_log(spdlog::level::warn)) return;
  static std::mutex mutex;
  static std::unordered_set<std::string> said;
  {
    std::lock_guard lock(mutex);
    // Bounded: messages name files and values, and a long session (a viewer streaming a
    // damaged dataset) must not keep every one. Past the bound a message may be said again.
    if (said.size() >= 4096) said.clear();
    if (!said.insert(message).second) return;
  }
  spdlog::warn("{}", message);
}

void assert_failed(const char* expr, const char* file, int line, const char* message) {
  spdlog::critical("assertion failed: {} ({}:{}): {}", expr, file, line, message);
  spdlog::shutdown();
  std::abort();
}

}  // namespace stipple
