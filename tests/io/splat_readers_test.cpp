// The splat readers against real files written by other software (../shared/data/splats, whose
// README gives the counts, SH degrees and the fixtures' expected values), synthetic files with
// known values, the same scene in two formats, and damaged input.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include <zlib.h>
#include <nlohmann/json.hpp>

#include "stipple/core/error.hpp"
#include "stipple/io/splat_readers.hpp"

namespace fs = std::filesystem;
using stipple::Error;
using namespace stipple::io;

namespace {

constexpr float kC0 = 0.28209479177387814f;

fs::path data_dir() {
  if (const char* env = std::getenv("STIPPLE_DATA_DIR")) return env;
#ifdef STIPPLE_SOURCE_DIR
  return fs::path(STIPPLE_SOURCE_DIR "/../shared/data");
#else
  return {};
#endif
}

#define REQUIRE_SPLATS(rel)                                                      \
  const fs::path file = data_dir() / "splats" / (rel);                           \
  if (data_dir().empty() || !fs::exists(file)) {                                 \
    GTEST_SKIP() << "test data " << file << " not found (set STIPPLE_DATA_DIR)"; \
  }

std::vector<uint8_t> bytes_of(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

glm::vec3 colour(const SplatSet& s, size_t i) {
  return 0.5f + kC0 * s.sh_dc[i];
}

// Every array sized for the count, every value finite, rotations unit, opacities in [0, 1].
void expect_well_formed(const SplatSet& s) {
  const size_t n = s.size();
  ASSERT_EQ(s.scales.size(), n);
  ASSERT_EQ(s.rotations.size(), n);
  ASSERT_EQ(s.opacities.size(), n);
  ASSERT_EQ(s.sh_dc.size(), n);
  ASSERT_EQ(s.sh_rest.size(), n * s.rest_count());
  for (size_t i = 0; i < n; ++i) {
    ASSERT_TRUE(std::isfinite(s.positions[i].x + s.positions[i].y + s.positions[i].z)) << i;
    ASSERT_NEAR(glm::length(s.rotations[i]), 1.0f, 1e-4f) << i;
    ASSERT_GE(s.opacities[i], 0.0f);
    ASSERT_LE(s.opacities[i], 1.0f);
    ASSERT_GE(std::min({s.scales[i].x, s.scales[i].y, s.scales[i].z}), 0.0f) << i;
  }
}

// The four splats of splat-transform's minimal.* fixtures, on the 2x2 grid of the README.
const glm::vec3 kGrid[4] = {{-1, 0, -1}, {0, 0, -1}, {-1, 0, 0}, {0, 0, 0}};
const glm::vec3 kGridColour[4] = {{1 / 3.f, 1 / 3.f, 0.5f},
                                  {2 / 3.f, 1 / 3.f, 0.5f},
                                  {1 / 3.f, 2 / 3.f, 0.5f},
                                  {2 / 3.f, 2 / 3.f, 0.5f}};

// Quaternions q and -q are the same rotation.
void expect_rotation(const glm::vec4& q, const glm::vec4& expected, float tol) {
  const float d = std::min(glm::length(q - expected), glm::length(q + expected));
  EXPECT_LT(d, tol) << q.x << " " << q.y << " " << q.z << " " << q.w;
}

struct FileCase {
  const char* path;
  size_t count;
  int degree;
  const char* format;
};

}  // namespace

TEST(SplatReaders, EveryFileDecodesToItsCountAndDegree) {
  const FileCase cases[] = {
      {"playcanvas-engine/biker.spz", 152746, 0, "SPZ v4"},
      {"playcanvas-engine/biker.compressed.ply", 152746, 0, "PlayCanvas compressed PLY"},
      {"playcanvas-engine/guitar.compressed.ply", 90854, 0, "PlayCanvas compressed PLY"},
      {"playcanvas-engine/test.ply", 64, 3, "PlayCanvas compressed PLY"},
      {"playcanvas-engine/wave_0001.sog", 4225, 0, "SOG v2"},
      {"splat-transform/minimal.splat", 4, 0, "antimatter15 .splat"},
      {"splat-transform/minimal.ksplat", 4, 0, ".ksplat (compression level 0)"},
      {"splat-transform/minimal-raw.spz", 4, 0, "SPZ v2 (not gzipped)"},
      {"splat-transform/minimal-v2.spz", 4, 0, "SPZ v2"},
      {"splat-transform/minimal-v3.spz", 4, 0, "SPZ v3"},
      {"splat-transform/minimal-v4.spz", 4, 0, "SPZ v4"},
      {"cesium-native/basic.glb", 1, 0, "glTF KHR_gaussian_splatting (SPZ)"},
      {"v3dg/donut_fused.ply", 45624, 0, "INRIA PLY"},
      {"gaussiansplats3d-pr477/lod5_tile_0.ply", 111, 3, "INRIA PLY"},
  };
  if (data_dir().empty() || !fs::exists(data_dir() / "splats"))
    GTEST_SKIP() << "test data " << data_dir() / "splats"
                 << " not found (set STIPPLE_DATA_DIR)";
  for (const FileCase& c : cases) {
    SCOPED_TRACE(c.path);
    const fs::path file = data_dir() / "splats" / c.path;
    // A .glb is content, not a splat file by its name (3D Tiles content decides).
    if (file.extension() != ".glb") {
      EXPECT_TRUE(is_splat_path(file.string()));
    }
    SplatSet s = read_splats(file.string());
    EXPECT_EQ(s.size(), c.count);
    EXPECT_EQ(s.sh_degree, c.degree);
    EXPECT_EQ(s.format, c.format);
    expect_well_formed(s);
    // The same bytes through decode_splats.
    auto bytes = bytes_of(file);
    EXPECT_EQ(decode_splats(bytes, file.string()).size(), c.count);
  }
}

TEST(SplatReaders, IsSplatPathByExtensionAndPlyHeader) {
  EXPECT_TRUE(is_splat_path("scene.SPZ"));
  EXPECT_TRUE(is_splat_path("https://example.com/a/scene.splat?x=1"));
  EXPECT_TRUE(is_splat_path("scene.ksplat"));
  EXPECT_TRUE(is_splat_path("scene.sog"));
  EXPECT_TRUE(is_splat_path("dir/meta.json"));
  EXPECT_FALSE(is_splat_path("tileset.json"));
  EXPECT_FALSE(is_splat_path("cloud.laz"));
  EXPECT_FALSE(is_splat_path("missing-file.ply"));
  // A point-cloud PLY is not a splat file.
  const fs::path ply = fs::temp_directory_path() / "stipple_points_only.ply";
  {
    std::ofstream out(ply, std::ios::binary);
    out << "ply\nformat binary_little_endian 1.0\nelement vertex 1\nproperty float x\n"
           "property float y\nproperty float z\nend_header\n";
    float xyz[3] = {1, 2, 3};
    out.write(reinterpret_cast<const char*>(xyz), sizeof xyz);
  }
  EXPECT_FALSE(is_splat_path(ply.string()));
  EXPECT_THROW(read_splats(ply.string()), Error);
  fs::remove(ply);
}

// A synthetic INRIA PLY with known values: activations, rotation order and normalisation, and
// f_rest's channel-major order turned coefficient-major.
TEST(SplatReaders, InriaPlyActivationsAndShOrder) {
  std::string header =
      "ply\nformat binary_little_endian 1.0\ncomment synthetic\nelement vertex 2\n"
      "property float x\nproperty float y\nproperty float z\n"
      "property float nx\nproperty float ny\nproperty float nz\n"
      "property float f_dc_0\nproperty float f_dc_1\nproperty float f_dc_2\n";
  for (int k = 0; k < 9; ++k) header += "property float f_rest_" + std::to_string(k) + "\n";
  header +=
      "property float opacity\nproperty float scale_0\nproperty float scale_1\n"
      "property float scale_2\nproperty float rot_0\nproperty float rot_1\nproperty float rot_2\n"
      "property float rot_3\nend_header\n";
  std::vector<uint8_t> bytes(header.begin(), header.end());
  auto put = [&](float v) {
    uint8_t b[4];
    std::memcpy(b, &v, 4);
    bytes.insert(bytes.end(), b, b + 4);
  };
  for (int i = 0; i < 2; ++i) {
    put(1.0f + i), put(2.0f), put(3.0f);                 // position
    put(0), put(0), put(1);                              // normal, ignored
    put(0.5f), put(-0.5f), put(1.0f);                    // f_dc
    for (int k = 0; k < 9; ++k) put(float(10 * i + k));  // f_rest R0 R1 R2 G0 G1 G2 B0 B1 B2
    put(0.0f);                                           // opacity logit: sigmoid 0.5
    put(0.0f), put(std::log(2.0f)), put(-1.0f);          // log scales
    put(2.0f), put(0.0f), put(0.0f), put(2.0f);          // w x y z, unnormalised
  }
  SplatSet s = decode_splats(bytes, "synthetic.ply");
  ASSERT_EQ(s.size(), 2u);
  EXPECT_EQ(s.sh_degree, 1);
  ASSERT_EQ(s.rest_count(), 3u);
  EXPECT_EQ(s.positions[1], glm::vec3(2, 2, 3));
  EXPECT_EQ(s.sh_dc[0], glm::vec3(0.5f, -0.5f, 1.0f));
  EXPECT_FLOAT_EQ(s.opacities[0], 0.5f);
  EXPECT_NEAR(s.scales[0].x, 1.0f, 1e-6f);
  EXPECT_NEAR(s.scales[0].y, 2.0f, 1e-6f);
  EXPECT_NEAR(s.scales[0].z, std::exp(-1.0f), 1e-6f);
  // rot_0 is w: (w, x, y, z) = (2, 0, 0, 2) -> (x, y, z, w) = (0, 0, 1, 1)/sqrt2.
  expect_rotation(s.rotations[0], glm::vec4(0, 0, 1, 1) / std::sqrt(2.0f), 1e-6f);
  // Coefficient k of splat i is (f_rest_k, f_rest_{3+k}, f_rest_{6+k}).
  for (int i = 0; i < 2; ++i)
    for (int k = 0; k < 3; ++k)
      EXPECT_EQ(s.sh_rest[size_t(i) * 3 + size_t(k)],
                glm::vec3(float(10 * i + k), float(10 * i + 3 + k), float(10 * i + 6 + k)));
}

TEST(SplatReaders, InriaPlyRealValues) {
  REQUIRE_SPLATS("v3dg/donut_fused.ply");
  SplatSet s = read_splats(file.string());
  // Splat 0 as Python's struct reads the file: x y z f_dc opacity scale rot.
  EXPECT_NEAR(s.positions[0].x, 0.018263084813952446, 1e-7);
  EXPECT_NEAR(s.positions[0].z, 0.040593795478343964, 1e-7);
  EXPECT_NEAR(s.sh_dc[0].y, 1.3836876153945923, 1e-6);
  EXPECT_NEAR(s.opacities[0], 1.0 / (1.0 + std::exp(-6.068385601043701)), 1e-6);
  EXPECT_NEAR(s.scales[0].x, std::exp(-4.831232070922852), 1e-7);
  const glm::vec4 q(0.2471696138381958f, -0.13596948981285095f, 0.25336384773254395f,
                    0.7263771891593933f);
  expect_rotation(s.rotations[0], q / glm::length(q), 1e-6f);
  // Its bounds (numpy over the file's x y z).
  glm::vec3 lo(INFINITY), hi(-INFINITY);
  for (const auto& p : s.positions) lo = glm::min(lo, p), hi = glm::max(hi, p);
  EXPECT_NEAR(lo.x, -0.10316952, 1e-6);
  EXPECT_NEAR(hi.y, 0.1095402, 1e-6);
  EXPECT_NEAR(lo.z, -0.00906719, 1e-6);
}

TEST(SplatReaders, PlyAsciiAndUnknownLayoutsAreErrors) {
  std::string ascii =
      "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float f_dc_0\n"
      "property float opacity\nproperty float scale_0\nproperty float rot_0\nend_header\n"
      "1 2 3 4 5\n";
  std::vector<uint8_t> bytes(ascii.begin(), ascii.end());
  try {
    decode_splats(bytes, "ascii.ply");
    FAIL() << "no error";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("ascii.ply"), std::string::npos);
    EXPECT_NE(std::string(e.what()).find("binary_little_endian"), std::string::npos);
  }
}

TEST(SplatReaders, MinimalSplatAndKsplat) {
  REQUIRE_SPLATS("splat-transform/minimal.splat");
  for (const char* f : {"splat-transform/minimal.splat", "splat-transform/minimal.ksplat"}) {
    SCOPED_TRACE(f);
    SplatSet s = read_splats((data_dir() / "splats" / f).string());
    ASSERT_EQ(s.size(), 4u);
    const uint8_t bytes[4][2] = {{85, 85}, {170, 85}, {85, 170}, {170, 170}};
    for (size_t i = 0; i < 4; ++i) {
      EXPECT_EQ(s.positions[i], kGrid[i]);
      EXPECT_NEAR(s.scales[i].x, 0.1f, 1e-6f);
      EXPECT_NEAR(s.scales[i].z, 0.1f, 1e-6f);
      EXPECT_NEAR(s.opacities[i], 230 / 255.0f, 1e-6f);
      // The colour bytes come back exactly (colour = byte / 255).
      EXPECT_NEAR(colour(s, i).r, bytes[i][0] / 255.0f, 1e-6f);
      EXPECT_NEAR(colour(s, i).g, bytes[i][1] / 255.0f, 1e-6f);
      EXPECT_NEAR(colour(s, i).b, 128 / 255.0f, 1e-6f);
      // Both files store (0,0,0,1) in the w-first order: a half turn about z (README).
      expect_rotation(s.rotations[i], glm::vec4(0, 0, 1, 0), 1e-2f);
    }
  }
}

TEST(SplatReaders, MinimalSpzV2AndRaw) {
  REQUIRE_SPLATS("splat-transform/minimal-v2.spz");
  for (const char* f : {"splat-transform/minimal-v2.spz", "splat-transform/minimal-raw.spz"}) {
    SCOPED_TRACE(f);
    SplatSet s = read_splats((data_dir() / "splats" / f).string());
    ASSERT_EQ(s.size(), 4u);
    const uint8_t bytes[4][2] = {{85, 85}, {170, 85}, {85, 170}, {170, 170}};
    for (size_t i = 0; i < 4; ++i) {
      EXPECT_EQ(s.positions[i], kGrid[i]);
      EXPECT_NEAR(s.scales[i].y, std::exp(123 / 16.0f - 10.0f), 1e-6f);
      EXPECT_NEAR(s.opacities[i], 230 / 255.0f, 1e-6f);
      // The writer stored colour bytes directly; SPZ's encoding reads them as such.
      EXPECT_NEAR(s.sh_dc[i].r, (bytes[i][0] / 255.0f - 0.5f) / 0.15f, 1e-5f);
      EXPECT_NEAR(s.sh_dc[i].g, (bytes[i][1] / 255.0f - 0.5f) / 0.15f, 1e-5f);
      expect_rotation(s.rotations[i], glm::vec4(0, 0, 0, 1), 1e-2f);
    }
  }
}

TEST(SplatReaders, MinimalSpzV3AndV4) {
  REQUIRE_SPLATS("splat-transform/minimal-v3.spz");
  for (const char* f : {"splat-transform/minimal-v3.spz", "splat-transform/minimal-v4.spz"}) {
    SCOPED_TRACE(f);
    SplatSet s = read_splats((data_dir() / "splats" / f).string());
    ASSERT_EQ(s.size(), 4u);
    for (size_t i = 0; i < 4; ++i) {
      // The writer stored SPZ's internal axes: z negated.
      EXPECT_EQ(s.positions[i], glm::vec3(kGrid[i].x, kGrid[i].y, -kGrid[i].z));
      EXPECT_NEAR(s.scales[i].x, 0.1f, 0.002f);
      EXPECT_NEAR(s.opacities[i], 0.9f, 0.003f);
      // Colour within SPZ's quantisation (one step: C0 / (0.15 * 255) = 0.0074).
      for (int c = 0; c < 3; ++c) EXPECT_NEAR(colour(s, i)[c], kGridColour[i][c], 0.0074f);
      expect_rotation(s.rotations[i], glm::vec4(0, 0, 0, 1), 1e-6f);
    }
    // splat-transform's own check of splat 0.
    EXPECT_NEAR(s.sh_dc[0].r, (1 / 3.f - 0.5f) / kC0, 0.03f);
    EXPECT_NEAR(s.sh_dc[0].b, 0.0f, 0.03f);
  }
}

TEST(SplatReaders, CesiumBasicGlb) {
  REQUIRE_SPLATS("cesium-native/basic.glb");
  auto bytes = bytes_of(file);
  SplatSet s = decode_splats_glb(bytes, file.string());
  ASSERT_EQ(s.size(), 1u);
  EXPECT_EQ(s.positions[0], glm::vec3(1, 2, 3));
  const glm::vec3 c = colour(s, 0);
  EXPECT_NEAR(c.r, 0.570062876f, 1e-6f);
  EXPECT_NEAR(c.g, 0.643813193f, 1e-6f);
  EXPECT_NEAR(c.b, 0.710188448f, 1e-6f);
  EXPECT_NEAR(s.opacities[0], 0.501960814f, 1e-6f);
  // cesium-native keeps the decoded quaternion as is; SplatSet's is normalised.
  const glm::vec4 q(0.003921628f, -0.709803939f, 0.709804058f, 0.0f);
  expect_rotation(s.rotations[0], q / glm::length(q), 1e-6f);
  EXPECT_NEAR(s.scales[0].x, 20.085537f, 1e-4f);
  EXPECT_NEAR(s.scales[0].y, 7.38905621f, 1e-5f);
  EXPECT_NEAR(s.scales[0].z, 2.71828175f, 1e-5f);
  // The node's matrix, column-major [1,0,0,0, 0,0,-1,0, 0,1,0,0, 0,0,0,1].
  EXPECT_EQ(s.transform[1], glm::dvec4(0, 0, -1, 0));
  EXPECT_EQ(s.transform[2], glm::dvec4(0, 1, 0, 0));
  EXPECT_EQ(s.transform[0], glm::dvec4(1, 0, 0, 0));
}

// The same four splats as .splat, .ksplat and SPZ v4 agree within SPZ's quantisation (v4's
// writer negated z, see above).
TEST(SplatReaders, MinimalFormatsAgree) {
  REQUIRE_SPLATS("splat-transform/minimal-v4.spz");
  auto a = read_splats((data_dir() / "splats/splat-transform/minimal.splat").string());
  auto b = read_splats((data_dir() / "splats/splat-transform/minimal.ksplat").string());
  auto c = read_splats((data_dir() / "splats/splat-transform/minimal-v4.spz").string());
  for (size_t i = 0; i < 4; ++i) {
    EXPECT_EQ(a.positions[i], b.positions[i]);
    EXPECT_EQ(a.positions[i] * glm::vec3(1, 1, -1), c.positions[i]);
    EXPECT_EQ(a.sh_dc[i], b.sh_dc[i]);
    EXPECT_EQ(a.opacities[i], b.opacities[i]);
    for (int k = 0; k < 3; ++k) {
      EXPECT_NEAR(colour(a, i)[k], colour(c, i)[k], 0.008f);
      EXPECT_NEAR(a.scales[i][k], c.scales[i][k], 0.002f);
    }
    EXPECT_NEAR(a.opacities[i], c.opacities[i], 0.003f);
  }
}
// PlayCanvas wrote one scene as SPZ v4 and as compressed PLY, in the same splat order. Its SPZ
// writer converted to SPZ's axes (y up, z back: y and z negated, the rotation conjugated by the
// half turn about x); within that, the two agree to their quantisation: SPZ's 12 fractional
// bits of position, 1/16 steps of log scale over [-10, 5.9], colour steps of
// C0 / (0.15 * 255) = 0.0074; the compressed PLY's 10-11 bits a chunk range, 8-bit colour.
TEST(SplatReaders, BikerSpzAndCompressedPlyAgree) {
  REQUIRE_SPLATS("playcanvas-engine/biker.spz");
  auto a = read_splats(file.string());
  auto b = read_splats((data_dir() / "splats/playcanvas-engine/biker.compressed.ply").string());
  ASSERT_EQ(a.size(), b.size());
  size_t clamped = 0;
  for (size_t i = 0; i < a.size(); ++i) {
    SCOPED_TRACE(i);
    ASSERT_LT(glm::length(a.positions[i] * glm::vec3(1, -1, -1) - b.positions[i]), 3e-4f);
    for (int k = 0; k < 3; ++k) {
      // SPZ cannot hold a log scale under -10: such scales are clamped there.
      if (std::log(b.scales[i][k]) < -9.97f) {
        ++clamped;
        ASSERT_NEAR(a.scales[i][k], std::exp(-10.0f), 1e-6f);
      } else {
        ASSERT_NEAR(std::log(a.scales[i][k] / b.scales[i][k]), 0.0f, 0.035f);
      }
      ASSERT_NEAR(colour(a, i)[k], colour(b, i)[k], 0.006f);
    }
    ASSERT_NEAR(a.opacities[i], b.opacities[i], 0.002f);
    expect_rotation(a.rotations[i] * glm::vec4(1, -1, -1, 1), b.rotations[i], 0.003f);
  }
  EXPECT_LT(clamped, a.size() / 10);
}

// The compressed PLY's 8-bit SH: channel-major bytes in the file, (b + 0.5) / 256 over [-4, 4).
TEST(SplatReaders, CompressedPlyShOrder) {
  REQUIRE_SPLATS("playcanvas-engine/test.ply");
  auto bytes = bytes_of(file);
  SplatSet s = decode_splats(bytes, file.string());
  ASSERT_EQ(s.sh_degree, 3);
  const std::string text(bytes.begin(), bytes.begin() + 4096);
  const size_t sh = text.find("end_header\n") + 11 + 1 * 18 * 4 + 64 * 16;
  for (size_t i : {size_t(0), size_t(63)})
    for (size_t j = 0; j < 45; ++j) {
      const uint8_t b = bytes[sh + i * 45 + j];
      const float n = b == 0 ? 0.0f : b == 255 ? 1.0f : (b + 0.5f) / 256.0f;
      EXPECT_EQ(s.sh_rest[i * 15 + j % 15][int(j / 15)], (n - 0.5f) * 8.0f) << i << " " << j;
    }
}

// Damaged copies of the small real files (every truncation, and bytes overwritten) decode or
// fail with an Error naming the file; none crashes or hangs (the sanitizer builds check more).
TEST(SplatReaders, DamagedFilesAreErrors) {
  if (data_dir().empty() || !fs::exists(data_dir() / "splats"))
    GTEST_SKIP() << "test data not found (set STIPPLE_DATA_DIR)";
  const char* files[] = {"splat-transform/minimal.splat",
                         "splat-transform/minimal.ksplat",
                         "splat-transform/minimal-raw.spz",
                         "splat-transform/minimal-v2.spz",
                         "splat-transform/minimal-v3.spz",
                         "splat-transform/minimal-v4.spz",
                         "cesium-native/basic.glb",
                         "playcanvas-engine/test.ply",
                         "gaussiansplats3d-pr477/lod5_tile_0.ply",
                         "playcanvas-engine/wave_0001.sog"};
  SplatLimits limits;
  limits.max_splats = 1 << 20;
  limits.max_inflated_bytes = 64 << 20;
  size_t errors = 0;
  for (const char* f : files) {
    SCOPED_TRACE(f);
    const auto whole = bytes_of(data_dir() / "splats" / f);
    const std::string name = (data_dir() / "splats" / f).string();
    auto attempt = [&](const std::vector<uint8_t>& bytes) {
      try {
        SplatSet s = decode_splats(bytes, name, limits);
        expect_well_formed(s);
      } catch (const Error& e) {
        ++errors;
        EXPECT_NE(std::string(e.what()).find(name), std::string::npos) << e.what();
      }
    };
    const size_t step = std::max<size_t>(1, whole.size() / 200);
    for (size_t n = 0; n < whole.size(); n += step)
      attempt(std::vector<uint8_t>(whole.begin(), whole.begin() + long(n)));
    uint32_t seed = 12345;
    for (int trial = 0; trial < 200; ++trial) {
      auto bytes = whole;
      for (int k = 0; k < 4; ++k) {
        seed = seed * 1664525u + 1013904223u;
        bytes[(seed >> 8) % bytes.size()] = uint8_t(seed >> 24);
      }
      attempt(bytes);
    }
  }
  EXPECT_GT(errors, 0u);
}

namespace {

// A GLB of one POINTS primitive holding `n` splats as float accessors named with `prefix`
// ("KHR_gaussian_splatting:" or the older "_"), SH degree 1, under a node translation.
std::vector<uint8_t> splat_glb(const std::string& prefix, size_t n, const char* drop = nullptr) {
  std::vector<float> bin;
  nlohmann::json accessors = nlohmann::json::array(), views = nlohmann::json::array();
  nlohmann::json attributes;
  auto add = [&](const std::string& name, const char* type, int k, auto value) {
    const size_t offset = bin.size() * 4;
    for (size_t i = 0; i < n; ++i)
      for (int c = 0; c < k; ++c) bin.push_back(value(i, c));
    views.push_back({{"buffer", 0}, {"byteOffset", offset}, {"byteLength", n * size_t(k) * 4}});
    accessors.push_back(
        {{"bufferView", views.size() - 1}, {"componentType", 5126}, {"count", n}, {"type", type}});
    attributes[name] = accessors.size() - 1;
  };
  add("POSITION", "VEC3", 3, [](size_t i, int c) { return float(i) + 0.25f * float(c); });
  add(prefix + "ROTATION", "VEC4", 4, [](size_t, int c) { return c == 2 ? 2.0f : 0.0f; });
  add(prefix + "SCALE", "VEC3", 3, [](size_t i, int c) { return 0.1f * float(i + 1) + float(c); });
  add(prefix + "OPACITY", "SCALAR", 1, [](size_t i, int) { return 0.5f + 0.1f * float(i); });
  add(prefix + "SH_DEGREE_0_COEF_0", "VEC3", 3, [](size_t i, int c) { return float(i) - c; });
  for (int k = 0; k < 3; ++k)
    add(prefix + "SH_DEGREE_1_COEF_" + std::to_string(k), "VEC3", 3,
        [k](size_t i, int c) { return float(100 * i + 10 * size_t(k) + size_t(c)); });
  nlohmann::json j = {
      {"asset", {{"version", "2.0"}}},
      {"extensionsUsed", {"KHR_gaussian_splatting"}},
      {"buffers", {{{"byteLength", bin.size() * 4}}}},
      {"bufferViews", views},
      {"accessors", accessors},
      {"meshes",
       {{{"primitives",
          {{{"mode", 0},
            {"attributes", attributes},
            {"extensions", {{"KHR_gaussian_splatting", nlohmann::json::object()}}}}}}}}},
      {"nodes", {{{"mesh", 0}, {"translation", {10, 20, 30}}}}},
      {"scenes", {{{"nodes", {0}}}}},
      {"scene", 0}};
  if (drop) j.erase(drop);
  std::string text = j.dump();
  while (text.size() % 4) text += ' ';
  std::vector<uint8_t> glb(12);
  auto u32 = [&](uint32_t v) {
    for (int b = 0; b < 4; ++b) glb.push_back(uint8_t(v >> (8 * b)));
  };
  u32(uint32_t(text.size()));
  u32(0x4E4F534A);
  glb.insert(glb.end(), text.begin(), text.end());
  u32(uint32_t(bin.size() * 4));
  u32(0x004E4942);
  const auto* raw = reinterpret_cast<const uint8_t*>(bin.data());
  glb.insert(glb.end(), raw, raw + bin.size() * 4);
  const uint32_t header[3] = {0x46546C67, 2, uint32_t(glb.size())};
  std::memcpy(glb.data(), header, 12);
  return glb;
}

}  // namespace

// Uncompressed KHR_gaussian_splatting, under the current and the older attribute names.
TEST(SplatReaders, GltfAttributes) {
  for (const std::string prefix : {"KHR_gaussian_splatting:", "_"}) {
    SCOPED_TRACE(prefix);
    const auto glb = splat_glb(prefix, 3);
    SplatSet s = decode_splats(glb, "synthetic.glb");
    ASSERT_EQ(s.size(), 3u);
    EXPECT_EQ(s.sh_degree, 1);
    EXPECT_EQ(s.format, "glTF KHR_gaussian_splatting");
    EXPECT_EQ(s.transform[3], glm::dvec4(10, 20, 30, 1));
    for (size_t i = 0; i < 3; ++i) {
      EXPECT_EQ(s.positions[i], glm::vec3(float(i), float(i) + 0.25f, float(i) + 0.5f));
      expect_rotation(s.rotations[i], glm::vec4(0, 0, 1, 0), 1e-6f);  // (x, y, z, w) order
      EXPECT_NEAR(s.scales[i].y, 0.1f * float(i + 1) + 1.0f, 1e-6f);  // linear
      EXPECT_NEAR(s.opacities[i], 0.5f + 0.1f * float(i), 1e-6f);
      EXPECT_EQ(s.sh_dc[i], glm::vec3(float(i), float(i) - 1, float(i) - 2));
      for (size_t k = 0; k < 3; ++k)
        EXPECT_EQ(s.sh_rest[i * 3 + k],
                  glm::vec3(float(100 * i + 10 * k), float(100 * i + 10 * k + 1),
                            float(100 * i + 10 * k + 2)));
    }
    // Without its buffers or views (a const lookup of a missing key once read freed memory).
    for (const char* key : {"buffers", "bufferViews", "accessors"})
      EXPECT_THROW(decode_splats(splat_glb(prefix, 3, key), "synthetic.glb"), Error) << key;
    // Truncated, it is an error naming the file.
    std::vector<uint8_t> cut(glb.begin(), glb.end() - 8);
    EXPECT_THROW(decode_splats(cut, "synthetic.glb"), Error);
  }
}

namespace {

// The entries of a zip whose entries are stored (as wave_0001.sog's are, sizes in the central
// directory: its local headers defer them to data descriptors), by walking the central
// directory of an archive without a comment: a reader independent of the one under test.
std::vector<std::pair<std::string, std::vector<uint8_t>>> stored_entries(
    const std::vector<uint8_t>& zip) {
  std::vector<std::pair<std::string, std::vector<uint8_t>>> out;
  auto u16 = [&](size_t p) { return uint32_t(zip[p]) | uint32_t(zip[p + 1]) << 8; };
  auto u32 = [&](size_t p) { return u16(p) | u16(p + 2) << 16; };
  const size_t eocd = zip.size() - 22;
  EXPECT_EQ(u32(eocd), 0x06054b50u);
  size_t at = u32(eocd + 16);
  for (uint32_t k = 0; k < u16(eocd + 10); ++k) {
    EXPECT_EQ(u16(at + 10), 0u) << "entry not stored";
    const size_t size = u32(at + 24), name = u16(at + 28), local = u32(at + 42);
    std::string entry(zip.begin() + long(at + 46), zip.begin() + long(at + 46 + name));
    const size_t data = local + 30 + u16(local + 26) + u16(local + 28);
    out.emplace_back(
        entry, std::vector<uint8_t>(zip.begin() + long(data), zip.begin() + long(data + size)));
    at += 46 + name + u16(at + 30) + u16(at + 32);
  }
  return out;
}

// A zip of the entries, each deflated (zlib, raw), with its central directory.
std::vector<uint8_t> deflated_zip(
    const std::vector<std::pair<std::string, std::vector<uint8_t>>>& entries) {
  std::vector<uint8_t> zip, dir;
  auto put = [](std::vector<uint8_t>& v, uint32_t x, int bytes) {
    for (int b = 0; b < bytes; ++b) v.push_back(uint8_t(x >> (8 * b)));
  };
  for (const auto& [name, data] : entries) {
    z_stream z{};
    deflateInit2(&z, 9, Z_DEFLATED, -15, 8, Z_DEFAULT_STRATEGY);
    std::vector<uint8_t> packed(deflateBound(&z, uLong(data.size())));
    z.next_in = const_cast<Bytef*>(data.data());
    z.avail_in = uInt(data.size());
    z.next_out = packed.data();
    z.avail_out = uInt(packed.size());
    deflate(&z, Z_FINISH);
    packed.resize(z.total_out);
    deflateEnd(&z);
    const uint32_t crc = uint32_t(crc32(0, data.data(), uInt(data.size())));
    const uint32_t local = uint32_t(zip.size());
    put(zip, 0x04034b50, 4), put(zip, 20, 2), put(zip, 0, 2), put(zip, 8, 2), put(zip, 0, 4);
    put(zip, crc, 4), put(zip, uint32_t(packed.size()), 4), put(zip, uint32_t(data.size()), 4);
    put(zip, uint32_t(name.size()), 2), put(zip, 0, 2);
    zip.insert(zip.end(), name.begin(), name.end());
    zip.insert(zip.end(), packed.begin(), packed.end());
    put(dir, 0x02014b50, 4), put(dir, 20, 2), put(dir, 20, 2), put(dir, 0, 2), put(dir, 8, 2);
    put(dir, 0, 4), put(dir, crc, 4), put(dir, uint32_t(packed.size()), 4);
    put(dir, uint32_t(data.size()), 4), put(dir, uint32_t(name.size()), 2), put(dir, 0, 2);
    put(dir, 0, 2), put(dir, 0, 2), put(dir, 0, 2), put(dir, 0, 4), put(dir, local, 4);
    dir.insert(dir.end(), name.begin(), name.end());
  }
  const uint32_t dir_at = uint32_t(zip.size());
  zip.insert(zip.end(), dir.begin(), dir.end());
  put(zip, 0x06054b50, 4), put(zip, 0, 2), put(zip, 0, 2);
  put(zip, uint32_t(entries.size()), 2), put(zip, uint32_t(entries.size()), 2);
  put(zip, uint32_t(dir.size()), 4), put(zip, dir_at, 4), put(zip, 0, 2);
  return zip;
}

void expect_same_splats(const SplatSet& a, const SplatSet& b) {
  ASSERT_EQ(a.size(), b.size());
  EXPECT_EQ(a.positions, b.positions);
  EXPECT_EQ(a.scales, b.scales);
  EXPECT_EQ(a.rotations, b.rotations);
  EXPECT_EQ(a.opacities, b.opacities);
  EXPECT_EQ(a.sh_dc, b.sh_dc);
  EXPECT_EQ(a.sh_rest, b.sh_rest);
}

}  // namespace

// wave_0001.sog (stored entries) read three ways: the archive, the same files deflated into a
// new archive, and unbundled beside a meta.json.
TEST(SplatReaders, SogBundledDeflatedAndUnbundled) {
  REQUIRE_SPLATS("playcanvas-engine/wave_0001.sog");
  const SplatSet sog = read_splats(file.string());
  const auto entries = stored_entries(bytes_of(file));
  ASSERT_EQ(entries.size(), 6u);
  const auto zip = deflated_zip(entries);
  expect_same_splats(decode_splats(zip, "deflated.sog"), sog);
  const fs::path dir = fs::temp_directory_path() / "stipple_sog_unbundled";
  fs::create_directories(dir);
  for (const auto& [name, data] : entries) {
    std::ofstream out(dir / name, std::ios::binary);
    out.write(reinterpret_cast<const char*>(data.data()), std::streamsize(data.size()));
  }
  EXPECT_TRUE(is_splat_path((dir / "meta.json").string()));
  expect_same_splats(read_splats((dir / "meta.json").string()), sog);
  // A missing image is an error naming it.
  fs::remove(dir / "quats.webp");
  try {
    read_splats((dir / "meta.json").string());
    FAIL() << "no error";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("quats.webp"), std::string::npos) << e.what();
  }
  fs::remove_all(dir);
  // Positions within meta.json's bounds after the log transform (sign(v) (e^|v| - 1)).
  for (const auto& p : sog.positions) {
    EXPECT_LE(std::fabs(p.x), std::expm1(1.4080441f) + 1e-5f);
    EXPECT_LE(p.y, 0.0f);
  }
}
