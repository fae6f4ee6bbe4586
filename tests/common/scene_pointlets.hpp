#pragma once
// Test input for the virtualized path: a fresh temporary folder with the generated scan
// (scene.las, 200,000 points) and its pointlet cache (scene.pointlets; m = 2000: k = 64, 3125
// pointlets), made once per test suite.
#include <unistd.h>

#include <filesystem>
#include <string>

#include "scene_las.hpp"
#include "stipple/pointcloud/pointlets.hpp"

namespace stipple::test {

inline std::filesystem::path make_scene_pointlets(const std::string& name) {
  namespace fs = std::filesystem;
  const fs::path dir =
      fs::temp_directory_path() / ("stipple-" + name + "-" + std::to_string(getpid()));
  fs::remove_all(dir);
  fs::create_directories(dir);
  write_scene_las(dir / "scene.las", 200000);
  pc::PointletBuildOptions build;
  build.pointlets = 2000;
  build.progress = false;
  pc::build_pointlet_cache({dir / "scene.las"}, dir / "scene.pointlets", build);
  return dir;
}

}  // namespace stipple::test
