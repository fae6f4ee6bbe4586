#pragma once
// The one error type of stipple: what went wrong, in words a user can act on (file and problem).
#include <stdexcept>
#include <string>

#include <fmt/format.h>

namespace stipple {

struct Error : std::runtime_error {
  using std::runtime_error::runtime_error;
};

template <typename... Args>
[[noreturn]] void fail(fmt::format_string<Args...> format, Args&&... args) {
  throw Error(fmt::format(format, std::forward<Args>(args)...));
}

}  // namespace stipple
