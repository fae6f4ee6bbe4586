// The web build writes no PNG files (libpng is not part of it): the page shows the canvas and
// tests read it back. A caller that asks for a file gets an error naming it.
#include "stipple/core/error.hpp"
#include "stipple/renderer/png.hpp"

namespace stipple::gpu {

void write_png(const std::filesystem::path& path, const Image&) {
  fail("{}: PNG files are not written by the web build (read the canvas instead)", path.string());
}

Image read_png(const std::filesystem::path& path) {
  fail("{}: PNG files are not read by the web build", path.string());
}

}  // namespace stipple::gpu
