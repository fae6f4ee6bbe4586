// Fuzzes the part.json reader of `stipple tile merge` (tiler::merge_parts): the input is the
// part.json of one part directory; every malformed one must end in stipple::Error.
#include <unistd.h>

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <string>

#include "stipple/core/error.hpp"
#include "stipple/tiler/tiler.hpp"

namespace fs = std::filesystem;

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  static const fs::path dir = [] {
    fs::path d = fs::temp_directory_path() / ("stipple-fuzz-part-" + std::to_string(::getpid()));
    fs::create_directories(d / "part");
    return d;
  }();
  {
    std::ofstream out(dir / "part" / "part.json", std::ios::binary | std::ios::trunc);
    out.write(reinterpret_cast<const char*>(data), std::streamsize(size));
  }
  stipple::tiler::MergeOptions options;
  options.parts = {(dir / "part").string()};
  options.output = (dir / "out").string();
  options.force = true;
  options.threads = 1;
  try {
    stipple::tiler::merge_parts(options);
  } catch (const stipple::Error&) {
  }
  return 0;
}
