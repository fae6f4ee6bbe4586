// 3D Tiles readers (pnts, glb points, subtrees, tileset.json) checked value by value against a
// corpus the test encodes itself; traversal (SSE, REPLACE/ADD, no holes, budget, ordering,
// cancellation) as a pure function; the streamer's memory budget over a camera flight.
#include <cmath>
#include <filesystem>
#include <functional>

#include <draco/compression/encode.h>
#include <draco/point_cloud/point_cloud_builder.h>
#include <gtest/gtest.h>
#include <meshoptimizer.h>

#include "stipple/core/error.hpp"
#include "stipple/io/fetch.hpp"
#include "stipple/io/glb_points.hpp"
#include "stipple/io/pnts.hpp"
#include "stipple/io/subtree.hpp"
#include "stipple/io/tileset.hpp"
#include "stipple/tiles3d/render_load.hpp"
#include "stipple/tiles3d/streamer.hpp"
#include "stipple/tiles3d/traversal.hpp"
#include "tiles_fixtures.hpp"

using namespace stipple;
using namespace stipple::test;
using nlohmann::json;
namespace fs = std::filesystem;

namespace {

fs::path temp_dir(const std::string& name) {
  return fresh_temp_dir("tiles-" + name);
}

// Writes a seed for the fuzzer when STIPPLE_WRITE_TILE_SEEDS names a folder.
void seed(const std::string& name, const Bytes& b) {
  if (const char* dir = std::getenv("STIPPLE_WRITE_TILE_SEEDS"))
    write_file(fs::path(dir) / name, b);
}

uint32_t rgba(uint8_t r, uint8_t g, uint8_t b, uint8_t a = 255) {
  return r | (g << 8) | (b << 16) | (uint32_t(a) << 24);
}

}  // namespace

TEST(Pnts, PositionRgbaNormalBatchIdAndBatchTable) {
  std::vector<float> pos = {1, 2, 3, -4, 5.5f, 6, 7, 8, -9};
  Bytes bin;
  append(bin, pos);
  size_t rgba_at = bin.size();
  bin.insert(bin.end(), {10, 20, 30, 40, 50, 60, 70, 80, 90, 100, 110, 120});
  size_t normal_at = bin.size();
  append(bin, std::vector<float>{0, 0, 1, 1, 0, 0, 0, 1, 0});
  size_t batch_at = bin.size();
  bin.insert(bin.end(), {1, 0, 1});
  json ft = {{"POINTS_LENGTH", 3},
             {"POSITION", {{"byteOffset", 0}}},
             {"RGBA", {{"byteOffset", rgba_at}}},
             {"NORMAL", {{"byteOffset", normal_at}}},
             {"BATCH_ID", {{"byteOffset", batch_at}, {"componentType", "UNSIGNED_BYTE"}}},
             {"BATCH_LENGTH", 2},
             {"MY_SEMANTIC", 1}};
  Bytes bt_bin;
  append(bt_bin, std::vector<uint16_t>{100, 200, 300, 400});
  json bt = {{"height", {1.5, 2.5}},
             {"name", {"a", "b"}},
             {"pair", {{"byteOffset", 0}, {"componentType", "UNSIGNED_SHORT"}, {"type", "VEC2"}}}};
  Bytes data = make_pnts(ft, bin, bt, bt_bin);
  seed("full.pnts", data);
  io::PointContent c = io::decode_pnts(data, "t.pnts");
  ASSERT_EQ(c.point_count, 3u);
  EXPECT_EQ(c.positions[1], glm::vec3(-4, 5.5f, 6));
  EXPECT_EQ(c.rgba[2], rgba(90, 100, 110, 120));
  EXPECT_EQ(c.normals[1], glm::vec3(1, 0, 0));
  EXPECT_EQ(c.batch_ids, (std::vector<uint32_t>{1, 0, 1}));
  EXPECT_EQ(c.batch_length, 2u);
  ASSERT_TRUE(c.attributes.count("height"));
  EXPECT_EQ(c.attributes["height"].values, (std::vector<double>{2.5, 1.5, 2.5}));
  ASSERT_TRUE(c.attributes.count("pair"));
  EXPECT_EQ(c.attributes["pair"].components, 2);
  EXPECT_EQ(c.attributes["pair"].values, (std::vector<double>{300, 400, 100, 200, 300, 400}));
  EXPECT_FALSE(c.attributes.count("name"));  // strings are reported, not attributes
  bool warned = false;
  for (const auto& w : c.warnings) warned |= w.find("MY_SEMANTIC") != std::string::npos;
  EXPECT_TRUE(warned);
}

TEST(Pnts, QuantizedRgbOct16pRtcAndIntBatchIds) {
  Bytes bin;
  append(bin, std::vector<uint16_t>{0, 0, 0, 65535, 32768, 65535});
  size_t rgb_at = bin.size();
  bin.insert(bin.end(), {1, 2, 3, 4, 5, 6});
  size_t oct_at = bin.size();
  bin.insert(bin.end(), {128, 255, 255, 128});  // ~(0,1,0) and ~(1,0,0)
  pad(bin, 4, 0);
  size_t batch_at = bin.size();
  append(bin, std::vector<uint32_t>{0, 70000});
  json ft = {{"POINTS_LENGTH", 2},
             {"RTC_CENTER", {1000.0, 2000.0, 3000.0}},
             {"QUANTIZED_VOLUME_OFFSET", {-10.0, -20.0, -30.0}},
             {"QUANTIZED_VOLUME_SCALE", {20.0, 40.0, 60.0}},
             {"POSITION_QUANTIZED", {{"byteOffset", 0}}},
             {"RGB", {{"byteOffset", rgb_at}}},
             {"NORMAL_OCT16P", {{"byteOffset", oct_at}}},
             {"BATCH_ID", {{"byteOffset", batch_at}, {"componentType", "UNSIGNED_INT"}}},
             {"BATCH_LENGTH", 70001}};
  Bytes data = make_pnts(ft, bin);
  seed("quantized.pnts", data);
  io::PointContent c = io::decode_pnts(data, "q.pnts");
  EXPECT_EQ(c.center, glm::dvec3(990, 1980, 2970));
  EXPECT_EQ(c.positions[0], glm::vec3(0));
  EXPECT_NEAR(c.positions[1].x, 20.0, 1e-5);
  EXPECT_NEAR(c.positions[1].y, 32768 / 65535.0 * 40.0, 1e-4);
  EXPECT_EQ(c.rgba[1], rgba(4, 5, 6));
  EXPECT_NEAR(c.normals[0].y, 1.0, 0.02);
  EXPECT_NEAR(c.normals[1].x, 1.0, 0.02);
  EXPECT_EQ(c.batch_ids[1], 70000u);
}

TEST(Pnts, Rgb565ConstantRgbaAndShortBatchIds) {
  Bytes bin;
  append(bin, std::vector<float>{0, 0, 0, 1, 1, 1});
  size_t c565 = bin.size();
  append(bin, std::vector<uint16_t>{0xF800, 0x07E0});  // red, green
  size_t ids = bin.size();
  append(bin, std::vector<uint16_t>{3, 2});
  json ft = {{"POINTS_LENGTH", 2},
             {"POSITION", {{"byteOffset", 0}}},
             {"RGB565", {{"byteOffset", c565}}},
             {"BATCH_ID", {{"byteOffset", ids}}},
             {"BATCH_LENGTH", 4}};
  io::PointContent c = io::decode_pnts(make_pnts(ft, bin), "c.pnts");
  EXPECT_EQ(c.rgba[0], rgba(255, 0, 0));
  EXPECT_EQ(c.rgba[1], rgba(0, 255, 0));
  EXPECT_EQ(c.batch_ids, (std::vector<uint32_t>{3, 2}));
  json ft2 = {
      {"POINTS_LENGTH", 2}, {"POSITION", {{"byteOffset", 0}}}, {"CONSTANT_RGBA", {9, 8, 7, 6}}};
  io::PointContent k = io::decode_pnts(make_pnts(ft2, bin), "k.pnts");
  EXPECT_TRUE(k.constant_color);
  EXPECT_EQ(k.rgba[1], rgba(9, 8, 7, 6));
}

TEST(Pnts, DracoPointCompression) {
  const int n = 50;
  draco::PointCloudBuilder builder;
  builder.Start(n);
  int pos = builder.AddAttribute(draco::GeometryAttribute::POSITION, 3, draco::DT_FLOAT32);
  int col = builder.AddAttribute(draco::GeometryAttribute::COLOR, 3, draco::DT_UINT8);
  int gen = builder.AddAttribute(draco::GeometryAttribute::GENERIC, 1, draco::DT_FLOAT32);
  for (int i = 0; i < n; ++i) {
    float p[3] = {float(i), float(i * 2), float(-i)};
    uint8_t c[3] = {uint8_t(i), uint8_t(i * 3), 7};
    float g = i * 0.5f;
    builder.SetAttributeValueForPoint(pos, draco::PointIndex(i), p);
    builder.SetAttributeValueForPoint(col, draco::PointIndex(i), c);
    builder.SetAttributeValueForPoint(gen, draco::PointIndex(i), &g);
  }
  auto cloud = builder.Finalize(false);
  ASSERT_TRUE(cloud);
  draco::Encoder encoder;
  encoder.SetEncodingMethod(draco::POINT_CLOUD_SEQUENTIAL_ENCODING);
  draco::EncoderBuffer buffer;
  ASSERT_TRUE(encoder.EncodePointCloudToBuffer(*cloud, &buffer).ok());
  Bytes bin(buffer.data(), buffer.data() + buffer.size());
  json ft = {{"POINTS_LENGTH", n},
             {"POSITION", {{"byteOffset", 0}}},
             {"RGB", {{"byteOffset", 0}}},
             {"extensions",
              {{"3DTILES_draco_point_compression",
                {{"properties",
                  {{"POSITION", cloud->attribute(pos)->unique_id()},
                   {"RGB", cloud->attribute(col)->unique_id()}}},
                 {"byteOffset", 0},
                 {"byteLength", bin.size()}}}}}};
  json bt = {{"intensity", {{"byteOffset", 0}, {"componentType", "FLOAT"}, {"type", "SCALAR"}}},
             {"extensions",
              {{"3DTILES_draco_point_compression",
                {{"properties", {{"intensity", cloud->attribute(gen)->unique_id()}}}}}}}};
  Bytes data = make_pnts(ft, bin, bt);
  seed("draco.pnts", data);
  io::PointContent c = io::decode_pnts(data, "d.pnts");
  EXPECT_EQ(c.format, "pnts+draco");
  ASSERT_EQ(c.point_count, size_t(n));
  for (int i = 0; i < n; ++i) {
    EXPECT_EQ(c.positions[i], glm::vec3(float(i), float(i * 2), float(-i)));
    EXPECT_EQ(c.rgba[i], rgba(uint8_t(i), uint8_t(i * 3), 7));
    EXPECT_EQ(c.attributes["intensity"].values[i], i * 0.5);
  }
}

TEST(Pnts, MalformedInputIsRejectedClearly) {
  Bytes bin;
  append(bin, std::vector<float>{0, 0, 0});
  json ft = {{"POINTS_LENGTH", 1}, {"POSITION", {{"byteOffset", 0}}}};
  Bytes good = make_pnts(ft, bin);
  auto rejects = [](Bytes b, const char* what) {
    try {
      io::decode_pnts(b, "bad.pnts");
      ADD_FAILURE() << "accepted: " << what;
    } catch (const Error& e) {
      EXPECT_NE(std::string(e.what()).find("bad.pnts"), std::string::npos) << e.what();
    }
  };
  Bytes truncated(good.begin(), good.end() - 4);
  rejects(truncated, "truncated");
  rejects(make_pnts({{"POINTS_LENGTH", 2}, {"POSITION", {{"byteOffset", 0}}}}, bin),
          "too many points");
  rejects(make_pnts({{"POINTS_LENGTH", 1}, {"POSITION", {{"byteOffset", 4000}}}}, bin),
          "offset outside");
  rejects(make_pnts({{"POINTS_LENGTH", 1}}, bin), "no positions");
  rejects(make_pnts({{"POINTS_LENGTH", 4e9}, {"POSITION", {{"byteOffset", 0}}}}, bin),
          "huge count");
  Bytes bad_json = good;
  bad_json[28] = '[';
  rejects(bad_json, "bad json");
  Bytes ids = bin;
  ids.push_back(5);
  rejects(make_pnts({{"POINTS_LENGTH", 1},
                     {"POSITION", {{"byteOffset", 0}}},
                     {"BATCH_ID", {{"byteOffset", 12}, {"componentType", "UNSIGNED_BYTE"}}},
                     {"BATCH_LENGTH", 2}},
                    ids),
          "batch id out of range");
}

TEST(Glb, InterleavedPointsWithNodeTransformsAndRtc) {
  // Two points, interleaved: float3 position + 4 normalized ubytes colour (stride 16).
  Bytes bin;
  auto vertex = [&](float x, float y, float z, std::vector<uint8_t> c) {
    append(bin, std::vector<float>{x, y, z});
    bin.insert(bin.end(), c.begin(), c.end());
  };
  vertex(1, 2, 3, {255, 0, 0, 255});
  vertex(-1, 0, 0, {0, 255, 0, 128});
  json j = {
      {"asset", {{"version", "2.0"}}},
      {"extensionsUsed", {"CESIUM_RTC"}},
      {"extensions", {{"CESIUM_RTC", {{"center", {100.0, 200.0, 300.0}}}}}},
      {"buffers", {{{"byteLength", bin.size()}}}},
      {"bufferViews", {{{"buffer", 0}, {"byteLength", bin.size()}, {"byteStride", 16}}}},
      {"accessors",
       {{{"bufferView", 0}, {"componentType", 5126}, {"count", 2}, {"type", "VEC3"}},
        {{"bufferView", 0},
         {"byteOffset", 12},
         {"componentType", 5121},
         {"normalized", true},
         {"count", 2},
         {"type", "VEC4"}}}},
      {"meshes",
       {{{"primitives", {{{"mode", 0}, {"attributes", {{"POSITION", 0}, {"COLOR_0", 1}}}}}}}}},
      {"nodes",
       {{{"translation", {10.0, 0.0, 0.0}}, {"children", {1}}},
        {{"mesh", 0}, {"scale", {2.0, 2.0, 2.0}}}}},
      {"scenes", {{{"nodes", {0}}}}}};
  Bytes data = make_glb(j, bin);
  seed("points.glb", data);
  io::PointContent c = io::decode_glb_points(data, "p.glb");
  ASSERT_EQ(c.point_count, 2u);
  // glTF (x, y, z) -> 3D Tiles (x, -z, y), after node transforms; then the RTC centre.
  glm::dvec3 p0 = c.center + glm::dvec3(c.positions[0]);
  glm::dvec3 p1 = c.center + glm::dvec3(c.positions[1]);
  EXPECT_NEAR(p0.x, 100 + 12, 1e-4);
  EXPECT_NEAR(p0.y, 200 - 6, 1e-4);
  EXPECT_NEAR(p0.z, 300 + 4, 1e-4);
  EXPECT_NEAR(p1.x, 100 + 8, 1e-4);
  EXPECT_EQ(c.rgba[0], rgba(255, 0, 0));
  // No material: glTF's default OPAQUE, which ignores COLOR_0's alpha (128 here).
  EXPECT_EQ(c.rgba[1], rgba(0, 255, 0));
  EXPECT_FALSE(c.alpha);
}

// glTF defines COLOR_0 as linear; stipple draws sRGB-encoded colours (as LAS and pnts give
// them), so a glb from any writer is converted with the sRGB transfer function: linear 0.5 is
// sRGB 187.5, the darkest 8-bit linear step 1/255 is sRGB 12.7. Alpha stays linear.
TEST(Glb, Color0IsLinear) {
  const std::vector<float> positions(15, 0.0f);
  const std::vector<uint8_t> linear8 = {0, 1, 10, 128, 255};       // normalized UNSIGNED_BYTE VEC3
  const std::vector<float> linear_f = {0.5f, 0.214f, 1.0f, 0.5f};  // FLOAT VEC4, one point
  Bytes bin;
  append(bin, positions);
  const size_t at8 = bin.size();
  for (uint8_t v : linear8) bin.insert(bin.end(), {v, v, v, 0});
  const size_t atf = bin.size();
  append(bin, linear_f);
  json j = {
      {"asset", {{"version", "2.0"}}},
      {"buffers", {{{"byteLength", bin.size()}}}},
      {"bufferViews",
       {{{"buffer", 0}, {"byteLength", 60}},
        {{"buffer", 0}, {"byteOffset", at8}, {"byteLength", 20}, {"byteStride", 4}},
        {{"buffer", 0}, {"byteOffset", atf}, {"byteLength", 16}}}},
      {"accessors",
       {{{"bufferView", 0}, {"componentType", 5126}, {"count", 5}, {"type", "VEC3"}},
        {{"bufferView", 1},
         {"componentType", 5121},
         {"normalized", true},
         {"count", 5},
         {"type", "VEC3"}},
        {{"bufferView", 0}, {"componentType", 5126}, {"count", 1}, {"type", "VEC3"}},
        {{"bufferView", 2}, {"componentType", 5126}, {"count", 1}, {"type", "VEC4"}}}},
      {"meshes",
       {{{"primitives",
          {{{"mode", 0}, {"attributes", {{"POSITION", 0}, {"COLOR_0", 1}}}},
           {{"mode", 0}, {"attributes", {{"POSITION", 2}, {"COLOR_0", 3}}}, {"material", 0}}}}}}},
      // BLEND, so that the alpha is kept (OPAQUE, the default, ignores it).
      {"materials", {{{"alphaMode", "BLEND"}}}},
      {"nodes", {{{"mesh", 0}}}}};
  io::PointContent c = io::decode_glb_points(make_glb(j, bin), "linear.glb");
  ASSERT_EQ(c.point_count, 6u);
  const uint8_t want[5] = {0, 13, 56, 188, 255};
  for (int i = 0; i < 5; ++i)
    EXPECT_EQ(c.rgba[size_t(i)], rgba(want[i], want[i], want[i])) << "point " << i;
  EXPECT_EQ(c.rgba[5], rgba(188, 127, 255, 128));  // alpha is not converted
}

TEST(Glb, QuantizedPositionsAndMeshoptCompression) {
  // KHR_mesh_quantization: SHORT positions dequantized by the node's scale; USHORT colours.
  std::vector<int16_t> q = {100, -200, 300, 0, 0, 0, 32767, 1, -32768, 0, 0, 0};  // stride 8
  Bytes raw;
  append(raw, q);
  std::vector<uint16_t> colors = {65535, 0, 0, 0, 0, 65535, 32768, 32768, 32768};
  // EXT_meshopt_compression: encode the position stream; buffer 1 is the empty fallback.
  std::vector<uint8_t> encoded(meshopt_encodeVertexBufferBound(3, 8));
  encoded.resize(meshopt_encodeVertexBuffer(encoded.data(), encoded.size(), q.data(), 3, 8));
  Bytes bin = encoded;
  pad(bin, 4, 0);
  size_t color_at = bin.size();
  append(bin, colors);
  json j = {
      {"asset", {{"version", "2.0"}}},
      {"extensionsRequired", {"KHR_mesh_quantization", "EXT_meshopt_compression"}},
      {"extensionsUsed", {"KHR_mesh_quantization", "EXT_meshopt_compression"}},
      {"buffers",
       {{{"byteLength", bin.size()}},
        {{"byteLength", 24}, {"extensions", {{"EXT_meshopt_compression", {{"fallback", true}}}}}}}},
      {"bufferViews",
       {{{"buffer", 1},
         {"byteLength", 24},
         {"byteStride", 8},
         {"extensions",
          {{"EXT_meshopt_compression",
            {{"buffer", 0},
             {"byteOffset", 0},
             {"byteLength", encoded.size()},
             {"byteStride", 8},
             {"count", 3},
             {"mode", "ATTRIBUTES"}}}}}},
        {{"buffer", 0}, {"byteOffset", color_at}, {"byteLength", 18}}}},
      {"accessors",
       {{{"bufferView", 0}, {"componentType", 5122}, {"count", 3}, {"type", "VEC3"}},
        {{"bufferView", 1},
         {"componentType", 5123},
         {"normalized", true},
         {"count", 3},
         {"type", "VEC3"}}}},
      {"meshes",
       {{{"primitives", {{{"mode", 0}, {"attributes", {{"POSITION", 0}, {"COLOR_0", 1}}}}}}}}},
      {"nodes", {{{"mesh", 0}, {"scale", {0.01, 0.01, 0.01}}}}}};
  Bytes data = make_glb(j, bin);
  seed("meshopt.glb", data);
  io::PointContent c = io::decode_glb_points(data, "m.glb");
  ASSERT_EQ(c.point_count, 3u);
  auto world = [&](int i) { return c.center + glm::dvec3(c.positions[i]); };
  EXPECT_NEAR(world(0).x, 1.0, 1e-5);
  EXPECT_NEAR(world(0).y, -3.0, 1e-5);  // -z
  EXPECT_NEAR(world(0).z, -2.0, 1e-5);  // y
  EXPECT_NEAR(world(2).x, -327.68, 1e-4);
  EXPECT_NEAR(world(1).z, 0.0, 1e-5);
  EXPECT_NEAR(world(1).y, -327.67, 1e-4);
  EXPECT_EQ(c.rgba[0], rgba(255, 0, 0));
  EXPECT_EQ(c.rgba[1], rgba(0, 0, 255));
  // 32768/65535 is linear 0.5: sRGB 187.5 (COLOR_0 is linear, see Glb.Color0IsLinear).
  EXPECT_EQ(c.rgba[2], rgba(188, 188, 188));
  // An unsupported required extension is refused by name.
  json k = j;
  k["extensionsRequired"].push_back("KHR_draco_mesh_compression");
  EXPECT_THROW(io::decode_glb_points(make_glb(k, bin), "k.glb"), Error);
  // An accessor past its buffer view is refused.
  json o = j;
  o["accessors"][1]["count"] = 4;
  EXPECT_THROW(io::decode_glb_points(make_glb(o, bin), "o.glb"), Error);
}

TEST(Subtree, BitstreamsConstantsAndIndexing) {
  EXPECT_EQ(io::subtree_tile_count(4, 3), 21u);
  EXPECT_EQ(io::availability_index(8, 2, 5), 9u + 5u);
  EXPECT_EQ(io::morton_index(1, 0, 0, 4), 1u);
  EXPECT_EQ(io::morton_index(0, 1, 0, 4), 2u);
  EXPECT_EQ(io::morton_index(3, 3, 0, 4), 15u);
  EXPECT_EQ(io::morton_index(0, 0, 1, 8), 4u);
  Bytes bin = {0b00000111, 0, 0b00000001, 0};  // tiles: root + children 0, 1; content: root
  json j = {{"buffers", {{{"byteLength", 4}}}},
            {"bufferViews",
             {{{"buffer", 0}, {"byteOffset", 0}, {"byteLength", 1}},
              {{"buffer", 0}, {"byteOffset", 2}, {"byteLength", 1}}}},
            {"tileAvailability", {{"bitstream", 0}, {"availableCount", 3}}},
            {"contentAvailability", {{{"bitstream", 1}}}},
            {"childSubtreeAvailability", {{"constant", 0}}}};
  Bytes data = make_subtree(j, bin);
  seed("a.subtree", data);
  io::Subtree s = io::decode_subtree(data, "s", 4, 2);
  EXPECT_TRUE(s.tiles.get(0));
  EXPECT_TRUE(s.tiles.get(2));
  EXPECT_FALSE(s.tiles.get(3));
  ASSERT_EQ(s.contents.size(), 1u);
  EXPECT_TRUE(s.contents[0].get(0));
  EXPECT_FALSE(s.contents[0].get(1));
  EXPECT_FALSE(s.child_subtrees.get(7));
  // 5 tiles need 5 bits: a bitstream of 0 bytes is too short.
  json bad = j;
  bad["bufferViews"][0]["byteLength"] = 0;
  EXPECT_THROW(io::decode_subtree(make_subtree(bad, bin), "s", 4, 2), Error);
  bad = j;
  bad["bufferViews"][0]["byteOffset"] = 100;
  EXPECT_THROW(io::decode_subtree(make_subtree(bad, bin), "s", 4, 2), Error);
}

TEST(Tileset, ImplicitQuadtreeWithChildSubtrees) {
  fs::path dir = temp_dir("implicit");
  // Root subtree (2 levels): root + children 0 and 3; content on all three; child subtree
  // under morton 0 of level 2 (tile (2,0,0)) available.
  json root_sub = {{"buffers", {{{"byteLength", 8}}}},
                   {"bufferViews",
                    {{{"buffer", 0}, {"byteOffset", 0}, {"byteLength", 1}},
                     {{"buffer", 0}, {"byteOffset", 1}, {"byteLength", 2}}}},
                   {"tileAvailability", {{"bitstream", 0}}},
                   {"contentAvailability", {{{"bitstream", 0}}}},
                   {"childSubtreeAvailability", {{"bitstream", 1}}}};
  write_file(dir / "subtrees/0.0.0.subtree",
             make_subtree(root_sub, {0b00010011, 0b1, 0, 0, 0, 0, 0, 0}));
  json leaf_sub = {{"tileAvailability", {{"constant", 1}}},
                   {"contentAvailability", {{{"constant", 1}}}},
                   {"childSubtreeAvailability", {{"constant", 0}}}};
  write_json(dir / "subtrees/2.0.0.subtree", leaf_sub);  // JSON subtree with the binary name
  json ts = {{"asset", {{"version", "1.1"}}},
             {"geometricError", 100},
             {"root",
              {{"boundingVolume", {{"box", {0, 0, 0, 8, 0, 0, 0, 8, 0, 0, 0, 1}}}},
               {"geometricError", 64},
               {"refine", "ADD"},
               {"content", {{"uri", "content/{level}/{x}_{y}.pnts"}}},
               {"implicitTiling",
                {{"subdivisionScheme", "QUADTREE"},
                 {"subtreeLevels", 2},
                 {"availableLevels", 4},
                 {"subtrees", {{"uri", "subtrees/{level}.{x}.{y}.subtree"}}}}}}}};
  write_json(dir / "tileset.json", ts);
  io::Tileset t = io::load_tileset((dir / "tileset.json").string());
  EXPECT_TRUE(t.errors.empty()) << t.errors.front();
  // Loading reads the root subtree only: root, (1,0,0), the root of the child subtree (2,0,0)
  // (its volume is known, its content is not), (1,1,1).
  ASSERT_EQ(t.tiles.size(), 4u);
  EXPECT_EQ(t.subtrees, 1u);
  EXPECT_EQ(t.pending, 1u);
  ASSERT_TRUE(t.tiles[2].pending);
  EXPECT_EQ(t.tiles[2].pending->kind, io::PendingChildren::Kind::Subtree);
  EXPECT_EQ(t.tiles[2].pending->uris[0], (dir / "subtrees/2.0.0.subtree").string());
  EXPECT_TRUE(t.tiles[2].contents.empty());
  EXPECT_EQ(t.tiles[2].depth, 2u);
  EXPECT_EQ(t.tiles[2].parent, 1);
  // Reading it adds its content and its 4 children at level 3.
  EXPECT_TRUE(io::expand_all(
      t, [](const std::string& u) { return io::fetch(u); }, {}, 1000));
  ASSERT_EQ(t.tiles.size(), 8u);
  EXPECT_EQ(t.subtrees, 2u);
  EXPECT_EQ(t.pending, 0u);
  EXPECT_EQ(t.tiles[2].contents, (std::vector<std::string>{(dir / "content/2/0_0.pnts").string()}));
  EXPECT_EQ(t.tiles[2].children, (std::vector<uint32_t>{4, 5, 6, 7}));
  EXPECT_EQ(t.tiles[0].children.size(), 2u);
  EXPECT_EQ(t.tiles[0].contents[0], (dir / "content/0/0_0.pnts").string());
  const io::Tile& c1 = t.tiles[t.tiles[0].children[1]];
  EXPECT_EQ(c1.contents[0], (dir / "content/1/1_1.pnts").string());
  EXPECT_DOUBLE_EQ(c1.geometric_error, 32);
  EXPECT_NEAR(c1.box.center.x, 4, 1e-12);
  EXPECT_NEAR(c1.box.center.y, 4, 1e-12);
  EXPECT_NEAR(c1.box.half_axes[0].x, 4, 1e-12);
  EXPECT_NEAR(c1.box.half_axes[2].z, 1, 1e-12);  // quadtree: z not split
  EXPECT_EQ(c1.refine, io::Refine::Add);
  const io::Tile& deep =
      *std::max_element(t.tiles.begin(), t.tiles.end(), [](const io::Tile& a, const io::Tile& b) {
        return a.depth != b.depth ? a.depth < b.depth : a.contents < b.contents;
      });
  EXPECT_EQ(deep.depth, 3u);
  EXPECT_DOUBLE_EQ(deep.geometric_error, 8);
  EXPECT_EQ(deep.contents[0], (dir / "content/3/1_1.pnts").string());
}

TEST(Tileset, ExternalTransformsRefineRegionAndCycles) {
  fs::path dir = temp_dir("external");
  json a = {{"asset", {{"version", "1.0"}}},
            {"geometricError", 50},
            {"extensionsUsed", {"MY_vendor_ext"}},
            {"root",
             {{"boundingVolume", {{"sphere", {0, 0, 0, 10}}}},
              {"geometricError", 40},
              {"refine", "ADD"},
              {"transform", {2, 0, 0, 0, 0, 2, 0, 0, 0, 0, 2, 0, 100, 0, 0, 1}},
              {"children",
               {{{"boundingVolume", {{"box", {1, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 1}}}},
                 {"geometricError", 10},
                 {"transform", {1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 5, 0, 1}},
                 {"content", {{"uri", "sub/b.json"}}}},
                {{"boundingVolume", {{"region", {-1.3, 0.6, -1.29, 0.61, 0, 100}}}},
                 {"geometricError", 5},
                 {"contents", {{{"uri", "x.pnts"}}, {{"uri", "y.glb"}}}}},
                {{"boundingVolume", {{"box", {0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 1}}}},
                 {"geometricError", 5},
                 {"content", {{"uri", "cycle.json"}}}}}}}}};
  json b = {{"asset", {{"version", "1.1"}}},
            {"geometricError", 10},
            {"root",
             {{"boundingVolume", {{"box", {0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 1}}}},
              {"geometricError", 2},
              {"content", {{"uri", "../c.pnts"}}}}}};
  json cycle = {{"asset", {{"version", "1.0"}}},
                {"geometricError", 10},
                {"root",
                 {{"boundingVolume", {{"box", {0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 1}}}},
                  {"geometricError", 2},
                  {"content", {{"uri", "tileset.json"}}}}}};
  write_json(dir / "tileset.json", a);
  write_json(dir / "sub/b.json", b);
  write_json(dir / "cycle.json", cycle);
  io::Tileset t = io::load_tileset((dir / "tileset.json").string());
  EXPECT_EQ(t.version, "1.0");
  EXPECT_EQ(t.warnings.size(), 1u);
  // Loading leaves external tilesets pending: root, child0, region child, cycle child.
  EXPECT_EQ(t.external_tilesets, 0u);
  ASSERT_EQ(t.tiles.size(), 4u);
  EXPECT_EQ(t.pending, 2u);
  ASSERT_TRUE(t.tiles[1].pending);
  EXPECT_EQ(t.tiles[1].pending->uris, (std::vector<std::string>{(dir / "sub/b.json").string()}));
  EXPECT_TRUE(t.tiles[1].children.empty());
  EXPECT_TRUE(t.errors.empty());
  // Read: b's root under child0, cycle.json's root under the cycle child.
  EXPECT_TRUE(io::expand_all(
      t, [](const std::string& u) { return io::fetch(u); }, {}, 1000));
  EXPECT_EQ(t.external_tilesets, 2u);
  EXPECT_EQ(t.pending, 0u);
  ASSERT_EQ(t.tiles.size(), 6u);
  EXPECT_DOUBLE_EQ(t.tiles[0].box.sphere_radius, 20);
  EXPECT_DOUBLE_EQ(t.tiles[0].box.center.x, 100);
  const io::Tile& ext_root = t.tiles[4];
  EXPECT_EQ(ext_root.parent, 1);
  EXPECT_EQ(ext_root.depth, 2u);
  EXPECT_EQ(t.tiles[1].children, (std::vector<uint32_t>{4}));
  EXPECT_EQ(ext_root.refine, io::Refine::Add);  // inherited across the external tileset
  EXPECT_EQ(ext_root.contents[0], (dir / "c.pnts").string());
  // Transforms chain: root scale 2 + translate 100, child translate (0,5,0).
  EXPECT_NEAR(t.tiles[1].box.center.x, 102, 1e-9);
  EXPECT_NEAR(t.tiles[1].box.center.y, 10, 1e-9);
  EXPECT_NEAR(glm::length(t.tiles[1].box.half_axes[0]), 2, 1e-9);
  const io::Tile& region = t.tiles[2];
  EXPECT_EQ(region.contents.size(), 2u);
  EXPECT_GT(glm::length(region.box.center), 6.3e6);  // ECEF, not moved by the transform
  // The cycle is seen where cycle.json refers back to the root: nothing is fetched for it.
  EXPECT_EQ(t.tiles[5].parent, 3);
  EXPECT_NE(t.tiles[5].error.find("cycle"), std::string::npos);
  EXPECT_FALSE(t.tiles[5].pending);
  EXPECT_EQ(t.errors.size(), 1u);

  json req = a;
  req["extensionsRequired"] = {"3DTILES_bogus"};
  write_json(dir / "req.json", req);
  try {
    io::load_tileset((dir / "req.json").string());
    ADD_FAILURE();
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("3DTILES_bogus"), std::string::npos);
  }
  write_file(dir / "broken.json", {'{', '"', 'a'});
  EXPECT_THROW(io::load_tileset((dir / "broken.json").string()), Error);
  EXPECT_THROW(io::load_tileset((dir / "missing.json").string()), Error);
}

// ---- traversal -------------------------------------------------------------------------

namespace {

// Root with content (error 100) over 4 children (error 0) tiling [0,100]^2 x [0,10] (Z-up).
io::Tileset two_level(io::Refine refine) {
  io::Tileset ts;
  auto box = [](double cx, double cy, double half) {
    io::Tile t;
    t.box.center = {cx, cy, 5};
    t.box.half_axes =
        glm::dmat3(glm::dvec3(half, 0, 0), glm::dvec3(0, half, 0), glm::dvec3(0, 0, 5));
    t.contents = {"x"};
    return t;
  };
  io::Tile root = box(50, 50, 50);
  root.geometric_error = 100;
  root.refine = refine;
  ts.tiles.push_back(root);
  for (int c = 0; c < 4; ++c) {
    io::Tile t = box(25 + 50 * (c & 1), 25 + 50 * (c >> 1), 25);
    t.parent = 0;
    t.depth = 1;
    t.refine = refine;
    ts.tiles[0].children.push_back(uint32_t(ts.tiles.size()));
    ts.tiles.push_back(t);
  }
  return ts;
}

tiles3d::View view_from_height(double h) {
  tiles3d::View v;
  v.height = 720;
  v.width = 1280;
  // Looking down at the middle from above (Z-up tileset; world is Y-up).
  v.camera.look_at(z_up_to_y_up({50, 40, h}), z_up_to_y_up({50, 50, 0}));
  return v;
}

}  // namespace

TEST(Traversal, ScreenSpaceErrorFollowsEquation1) {
  tiles3d::View v;
  v.height = 1000;
  v.camera.fov_y = glm::radians(90.0);
  EXPECT_NEAR(tiles3d::screen_space_error(2.0, 100.0, v), 2.0 * 500.0 / 100.0, 1e-9);
}

TEST(Traversal, ReplaceKeepsParentUntilChildrenLoad) {
  io::Tileset ts = two_level(io::Refine::Replace);
  tiles3d::TraversalOptions opt;
  std::vector<tiles3d::TileState> st(ts.tiles.size());
  // Far away: the root is enough.
  auto far = tiles3d::select_tiles(ts, view_from_height(1e6), st, opt, 1);
  ASSERT_EQ(far.loads.size(), 1u);
  EXPECT_EQ(far.loads[0].tile, 0u);
  // Close: the children are wanted; with the root loaded and children not, the root renders.
  st[0].state = tiles3d::LoadState::Loaded;
  auto near = tiles3d::select_tiles(ts, view_from_height(60), st, opt, 2);
  EXPECT_EQ(near.render, (std::vector<uint32_t>{0}));
  EXPECT_EQ(near.loads.size(), 4u);
  // Requests are ordered by SSE (closest child first for equal errors: by distance).
  for (size_t i = 1; i < near.loads.size(); ++i)
    EXPECT_TRUE(near.loads[i - 1].sse > near.loads[i].sse ||
                (near.loads[i - 1].sse == near.loads[i].sse &&
                 near.loads[i - 1].distance <= near.loads[i].distance));
  // Three of four loaded: still the root (no holes).
  for (int c = 1; c <= 3; ++c) st[c].state = tiles3d::LoadState::Loaded;
  auto partial = tiles3d::select_tiles(ts, view_from_height(60), st, opt, 3);
  EXPECT_EQ(partial.render, (std::vector<uint32_t>{0}));
  // All loaded: the children replace the root.
  st[4].state = tiles3d::LoadState::Loaded;
  auto full = tiles3d::select_tiles(ts, view_from_height(60), st, opt, 4);
  EXPECT_EQ(full.render.size(), 4u);
  EXPECT_EQ(std::count(full.render.begin(), full.render.end(), 0u), 0);
}

TEST(Traversal, AddRendersParentAndChildren) {
  io::Tileset ts = two_level(io::Refine::Add);
  std::vector<tiles3d::TileState> st(ts.tiles.size(), {tiles3d::LoadState::Loaded, 10, 0});
  auto sel = tiles3d::select_tiles(ts, view_from_height(60), st, {}, 1);
  EXPECT_EQ(sel.render.size(), 5u);
}

TEST(Traversal, FrustumCullingAndCancellation) {
  io::Tileset ts = two_level(io::Refine::Replace);
  std::vector<tiles3d::TileState> st(ts.tiles.size());
  st[0].state = tiles3d::LoadState::Loaded;
  // Looking at the corner of child 1 only (x 50..100, y 0..50), close.
  tiles3d::View v;
  v.camera.fov_y = glm::radians(30.0);
  v.camera.look_at(z_up_to_y_up({90, 10, 20}), z_up_to_y_up({95, 5, 0}));
  for (int c = 1; c <= 4; ++c) st[c].state = tiles3d::LoadState::Loading;
  auto sel = tiles3d::select_tiles(ts, v, st, {}, 1);
  EXPECT_GT(sel.culled, 0u);
  ASSERT_FALSE(sel.cancel.empty());
  // Child 1 (the visible one) is not cancelled; culled children are.
  EXPECT_EQ(std::count(sel.cancel.begin(), sel.cancel.end(), 2u), 0);
  EXPECT_EQ(std::count(sel.cancel.begin(), sel.cancel.end(), 4u), 1);
}

TEST(Traversal, BudgetEvictsLeastRecentlyUsedUnusedTiles) {
  io::Tileset ts = two_level(io::Refine::Replace);
  std::vector<tiles3d::TileState> st(ts.tiles.size(), {tiles3d::LoadState::Loaded, 100, 0});
  st[1].last_used = 5;
  st[2].last_used = 3;
  st[3].last_used = 7;
  st[4].last_used = 1;
  tiles3d::TraversalOptions opt;
  opt.memory_budget = 250;
  // Far: only the root is used; the children go, oldest first, until 250 bytes remain.
  auto sel = tiles3d::select_tiles(ts, view_from_height(1e6), st, opt, 10);
  EXPECT_EQ(sel.render, (std::vector<uint32_t>{0}));
  EXPECT_EQ(sel.evict, (std::vector<uint32_t>{4, 2, 1}));
  bool fits = true;
  auto none = tiles3d::make_room(st, 1000, 300, 10, &fits);
  EXPECT_FALSE(fits);
}

TEST(Streamer, MemoryBudgetHoldsOverACameraFlight) {
  fs::path dir = temp_dir("flight");
  int tiles = write_grid_tileset(dir, 4, 2000);  // 85 tiles x 2000 points
  auto ts = std::make_shared<io::Tileset>(io::load_tileset((dir / "tileset.json").string()));
  ASSERT_EQ(int(ts->tiles.size()), tiles);
  tiles3d::StreamerOptions opt;
  opt.threads = 2;
  opt.traversal.memory_budget = 1'200'000;  // ~ 30 tiles of the 85
  opt.traversal.max_sse = 4;
  tiles3d::TileStreamer streamer(ts, opt);
  uint64_t total = 0;
  int frames = 0;
  for (int step = 0; step <= 40; ++step) {
    double x = 25 * step;
    tiles3d::View v;
    v.camera.look_at(z_up_to_y_up({x, -50, 120}), z_up_to_y_up({x, 200, 0}));
    for (int i = 0; i < 20; ++i) {
      const auto& sel = streamer.update(v);
      ++frames;
      auto s = streamer.stats();
      ASSERT_LE(s.resident_bytes, opt.traversal.memory_budget) << "frame " << frames;
      for (uint32_t t : sel.render) ASSERT_NE(streamer.content(t), nullptr);
      if (streamer.idle()) break;
      streamer.wait_for_progress();
    }
  }
  auto s = streamer.stats();
  total = s.loads_completed;
  EXPECT_GT(total, 40u);
  EXPECT_GT(s.evictions, 0u);
  EXPECT_LE(s.peak_resident_bytes, opt.traversal.memory_budget);
  EXPECT_TRUE(streamer.errors().empty());
}

// has_results: a finished load waits for the next update(), which takes it in (a front end that
// draws only on change runs a frame then); none is left once it has.
TEST(Streamer, SaysWhenAFinishedLoadWaitsForTheNextUpdate) {
  fs::path dir = temp_dir("results");
  write_grid_tileset(dir, 2, 500);
  auto ts = std::make_shared<io::Tileset>(io::load_tileset((dir / "tileset.json").string()));
  tiles3d::StreamerOptions opt;
  opt.threads = 1;
  tiles3d::TileStreamer streamer(ts, opt);
  EXPECT_FALSE(streamer.has_results());
  tiles3d::View v;
  v.camera.look_at(z_up_to_y_up({500, -500, 800}), z_up_to_y_up({500, 500, 0}));
  streamer.update(v);
  ASSERT_FALSE(streamer.idle());
  int loads = 0;
  while (!streamer.idle()) {
    streamer.wait_for_progress();
    EXPECT_TRUE(streamer.has_results());
    const uint64_t before = streamer.stats().loads_completed + streamer.stats().expansions;
    streamer.update(v);
    EXPECT_GT(streamer.stats().loads_completed + streamer.stats().expansions, before);
    ++loads;
  }
  EXPECT_GT(loads, 0);
  EXPECT_FALSE(streamer.has_results());
  EXPECT_TRUE(streamer.errors().empty());
}

TEST(Streamer, RenderLoadConvertsTilesToChunks) {
  fs::path dir = temp_dir("render");
  write_grid_tileset(dir, 2, 500);
  tiles3d::RenderLoadOptions opt;
  auto r = tiles3d::load_tileset_for_render((dir / "tileset.json").string(), opt);
  EXPECT_TRUE(r.errors.empty());
  EXPECT_GT(r.cloud.point_count, 0u);
  EXPECT_EQ(r.cloud.chunks.size(), r.tiles_rendered);
  // Points lie inside the root volume [0,1000]^2 x [0,1000] (Z-up) -> world Y-up.
  EXPECT_GE(r.cloud.world_bounds.min.x, -1e-3);
  EXPECT_LE(r.cloud.world_bounds.max.x, 1000 + 1e-3);
  EXPECT_GE(r.cloud.world_bounds.min.y, -1e-3);  // world y = source z
}
