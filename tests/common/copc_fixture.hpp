#pragma once
// COPC files written for the tests: `stipple generate` makes a LAS, tests/tools/write_copc.py
// (laspy + lazrs from PyPI, in the venv scripts/setup.sh makes) turns it into COPC with a deep,
// paged hierarchy, or a damaged one. Empty path where Python or lazrs is missing.
#include <cstdlib>
#include <filesystem>
#include <string>

namespace stipple::test {

inline std::string copc_python() {
  const std::filesystem::path py =
      std::filesystem::path(STIPPLE_SOURCE_DIR) / ".deps" / "py3dtiles" / "bin" / "python";
  if (!std::filesystem::exists(py)) return {};
  const std::string check = py.string() + " -c 'import laspy, lazrs' >/dev/null 2>&1";
  return std::system(check.c_str()) == 0 ? py.string() : std::string();
}

// Writes `out` from a generated scene of `points` points; `args` go to write_copc.py.
inline bool write_test_copc(const std::filesystem::path& out, uint64_t points,
                            const std::string& args) {
  const std::string py = copc_python();
  if (py.empty()) return false;
  const std::filesystem::path las = out.string() + ".src.las";
  if (!std::filesystem::exists(las)) {
    const std::string gen = std::string(STIPPLE_BINARY) + " generate -n " + std::to_string(points) +
                            " -o " + las.string() + " >/dev/null 2>&1";
    if (std::system(gen.c_str()) != 0) return false;
  }
  const std::string cmd = py + " " + STIPPLE_SOURCE_DIR + "/tests/tools/write_copc.py " +
                          las.string() + " " + out.string() + " " + args + " >/dev/null";
  return std::system(cmd.c_str()) == 0;
}

}  // namespace stipple::test

#define STIPPLE_REQUIRE_COPC_WRITER()                                                           \
  if (::stipple::test::copc_python().empty())                                                   \
  GTEST_SKIP() << "laspy/lazrs not installed (scripts/setup.sh puts them in .deps/py3dtiles): " \
                  "tests of written COPC files skipped"
