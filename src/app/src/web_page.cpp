#include "stipple/app/web_page.hpp"

#include <cstdlib>
#include <system_error>

#include <fmt/format.h>

#include "stipple/core/atomic_file.hpp"
#include "stipple/core/error.hpp"

namespace stipple::app {
namespace fs = std::filesystem;

namespace {

bool holds_viewer(const fs::path& dir) {
  std::error_code ec;
  for (const auto& f : kWebViewerFiles)
    if (!fs::is_regular_file(dir / f, ec)) return false;
  return true;
}

// "stipple.html, stipple.mjs, ..." for the messages.
std::string viewer_files() {
  std::string names;
  for (const auto& f : kWebViewerFiles) names += (names.empty() ? "" : ", ") + f;
  return names;
}

}  // namespace

fs::path find_web_viewer() {
  if (const char* env = std::getenv("STIPPLE_WEB_DIR"); env && *env) {
    if (!holds_viewer(env))
      fail(
          "STIPPLE_WEB_DIR={} does not hold the web viewer ({}): build it with "
          "scripts/build-web.sh",
          env, viewer_files());
    return env;
  }
  std::vector<fs::path> places;
  std::error_code ec;
  const fs::path exe = fs::read_symlink("/proc/self/exe", ec);
  if (!ec) {
    places.push_back(exe.parent_path().parent_path() / "share/stipple/web");
    places.push_back(exe.parent_path().parent_path() / "build-web");
  }
#ifdef STIPPLE_SOURCE_DIR
  places.push_back(fs::path(STIPPLE_SOURCE_DIR) / "build-web");
#endif
  std::string looked;
  for (const auto& p : places) {
    if (holds_viewer(p)) return p;
    looked += (looked.empty() ? "" : ", ") + p.lexically_normal().string();
  }
  fail(
      "--page: the web viewer ({}) is not built: looked in {}; build it with "
      "scripts/build-web.sh, or name its folder with STIPPLE_WEB_DIR",
      viewer_files(), looked.empty() ? std::string("no place") : looked);
}

fs::path write_web_page(const fs::path& dir) {
  const fs::path viewer = find_web_viewer();
  std::error_code ec;
  auto copy = [&](const std::string& name) {
    fs::copy_file(viewer / name, dir / name, fs::copy_options::overwrite_existing, ec);
    if (ec)
      fail("--page: cannot copy {} to {}: {}", (viewer / name).string(), dir.string(),
           ec.message());
  };
  for (const auto& f : kWebViewerFiles) copy(f);
  for (const auto& f : kWebViewerOptionalFiles)
    if (fs::is_regular_file(viewer / f, ec)) copy(f);
  write_file_atomically(
      (dir / "index.html").string(),
      "<!doctype html>\n<meta charset=\"utf-8\">\n<title>stipple</title>\n"
      "<meta http-equiv=\"refresh\" content=\"0; url=stipple.html?url=tileset.json\">\n"
      "<a href=\"stipple.html?url=tileset.json\">Open the tileset in the stipple viewer</a>\n");
  return viewer;
}

}  // namespace stipple::app
