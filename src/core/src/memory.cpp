#include "stipple/core/memory.hpp"

#include <sys/resource.h>
#include <unistd.h>

#include <cstdio>
#include <string>

#include "stipple/core/error.hpp"

namespace stipple {

uint64_t resident_bytes() {
  std::FILE* f = std::fopen("/proc/self/statm", "r");
  if (!f) return 0;
  unsigned long long size = 0, resident = 0;
  const int got = std::fscanf(f, "%llu %llu", &size, &resident);
  std::fclose(f);
  const long page = sysconf(_SC_PAGESIZE);
  return got == 2 && page > 0 ? uint64_t(resident) * uint64_t(page) : 0;
}

uint64_t peak_resident_bytes() {
  rusage usage{};
  if (getrusage(RUSAGE_SELF, &usage) != 0) return 0;
  return uint64_t(usage.ru_maxrss) * 1024;
}

uint64_t parse_size(const std::string& text) {
  if (text.empty()) fail("empty size");
  size_t used = 0;
  double v = 0;
  try {
    v = std::stod(text, &used);
  } catch (...) {
    fail("'{}' is not a size (e.g. 2G, 512M)", text);
  }
  std::string unit = text.substr(used);
  double mult = 1;
  if (unit == "k" || unit == "K" || unit == "KB" || unit == "KiB")
    mult = 1024.0;
  else if (unit == "m" || unit == "M" || unit == "MB" || unit == "MiB")
    mult = 1024.0 * 1024;
  else if (unit == "g" || unit == "G" || unit == "GB" || unit == "GiB")
    mult = 1024.0 * 1024 * 1024;
  else if (!unit.empty())
    fail("'{}' is not a size (e.g. 2G, 512M)", text);
  if (!(v > 0)) fail("size '{}' must be positive", text);
  return uint64_t(v * mult);
}

}  // namespace stipple
