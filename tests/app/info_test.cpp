// `stipple info` on the tiler's output: the total point count comes from the tile headers (no
// point decoded) and equals the input's; contents are counted by type; --max-tiles still caps
// what is read; a tileset of meshes is named as not drawn.
#include <gtest/gtest.h>
#include <unistd.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <string>

#include <nlohmann/json.hpp>

#include "test_util.hpp"

using namespace stipple;
using namespace stipple::test;
namespace fs = std::filesystem;
using nlohmann::json;

namespace {

fs::path work_dir() {
  static const fs::path d = [] {
    fs::path p = fs::temp_directory_path() / ("stipple-info-test-" + std::to_string(::getpid()));
    fs::create_directories(p);
    return p;
  }();
  return d;
}

json info_json(const std::string& args) {
  // The log goes to stderr; only the JSON is kept.
  CommandResult r =
      run_command(std::string("{ ") + STIPPLE_BINARY + " info --json " + args + " 2>/dev/null; }");
  EXPECT_EQ(r.exit_code, 0) << r.output;
  return json::parse(r.output, nullptr, false);
}

}  // namespace

TEST(Info, TilesetTotalsFromTileHeaders) {
  const fs::path las = work_dir() / "gen.las";
  ASSERT_EQ(run_stipple("generate -n 40000 -o " + las.string()).exit_code, 0);
  for (const char* format : {"glb", "pnts"}) {
    const fs::path out = work_dir() / format;
    CommandResult t = run_stipple("tile " + las.string() + " -o " + out.string() +
                                  " --max-node-points 4000 --force --format " + format);
    ASSERT_EQ(t.exit_code, 0) << t.output;
    json j = info_json((out / "tileset.json").string());
    ASSERT_FALSE(j.is_discarded());
    EXPECT_EQ(j["points"], 40000) << format;
    EXPECT_EQ(j["contents_by_type"].size(), 1u);
    EXPECT_EQ(j["contents_by_type"][format], j["contents"]) << format;
    EXPECT_TRUE(j["contents_not_drawn"].empty());
    // The text form says it too.
    CommandResult text = run_stipple("info " + (out / "tileset.json").string());
    EXPECT_NE(text.output.find("points:     40000"), std::string::npos) << text.output;
    // --max-tiles caps the tiles read, and so the points counted.
    json capped = info_json("--max-tiles 1 " + (out / "tileset.json").string());
    EXPECT_LT(capped["points"].get<uint64_t>(), 40000u);
  }
}

TEST(Info, MeshContentIsNamedAsNotDrawn) {
  const fs::path dir = work_dir() / "mesh";
  fs::create_directories(dir);
  std::string b3dm = "b3dm";
  for (uint32_t v : {1u, 28u, 0u, 0u, 0u, 0u}) b3dm.append(reinterpret_cast<const char*>(&v), 4);
  std::ofstream(dir / "m.b3dm", std::ios::binary) << b3dm;
  std::ofstream(dir / "tileset.json")
      << R"({"asset":{"version":"1.0"},"geometricError":10,"root":{"boundingVolume":)"
      << R"({"box":[0,0,0,5,0,0,0,5,0,0,0,5]},"geometricError":0,"content":{"uri":"m.b3dm"}}})";
  json j = info_json((dir / "tileset.json").string());
  EXPECT_EQ(j["points"], 0);
  EXPECT_EQ(j["contents_not_drawn"]["b3dm"], 1);
  CommandResult text = run_stipple("info " + (dir / "tileset.json").string());
  EXPECT_NE(text.output.find("warning: 1 of 1 contents are b3dm (batched 3D models), which "
                             "stipple does not draw"),
            std::string::npos)
      << text.output;
}

// A splat file: format, count, SH degree and bounds (donut_fused.ply's as numpy reads them, in
// the Y-up frame: a PLY's y and z negated, SplatSet::transform).
TEST(Info, SplatFile) {
  const char* data = std::getenv("STIPPLE_DATA_DIR");
  const fs::path file = fs::path(data ? data : STIPPLE_SOURCE_DIR "/../shared/data") / "splats" /
                        "v3dg" / "donut_fused.ply";
  if (!fs::exists(file)) GTEST_SKIP() << file << " not found (set STIPPLE_DATA_DIR)";
  json j = info_json(file.string());
  ASSERT_FALSE(j.is_discarded());
  EXPECT_EQ(j["format"], "INRIA PLY");
  EXPECT_EQ(j["splats"], 45624);
  EXPECT_EQ(j["sh_degree"], 0);
  EXPECT_NEAR(j["bounds"]["min"][0].get<double>(), -0.10316952, 1e-6);
  EXPECT_NEAR(j["bounds"]["max"][1].get<double>(), 0.09762745, 1e-6);  // the file's min y, negated
  EXPECT_NEAR(j["bounds"]["min"][1].get<double>(), -0.1095402, 1e-6);  // its max y, negated
  CommandResult text = run_stipple("info " + file.string());
  EXPECT_EQ(text.exit_code, 0);
  EXPECT_NE(text.output.find("INRIA PLY: 45624 splats, SH degree 0"), std::string::npos)
      << text.output;
}
