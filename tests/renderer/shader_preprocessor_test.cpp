// The WGSL include preprocessor over an in-memory file system: resolution, include-once,
// errors, and the line map that turns compiler messages back into file:line.
#include <gtest/gtest.h>

#include <cstdlib>
#include <filesystem>
#include <functional>
#include <map>
#include <sstream>

#include "stipple/core/error.hpp"
#include "stipple/renderer/shader_preprocessor.hpp"
#include "stipple/renderer/shaders.hpp"

using namespace stipple;
using gpu::SourceLocation;

namespace {

std::string error_of(const std::function<void()>& f) {
  try {
    f();
  } catch (const Error& e) {
    return e.what();
  }
  return "(no error)";
}

// Every output line must map to the line of its file with the same text (or be the marker of a
// skipped include).
void expect_map_matches_sources(const gpu::PreprocessedShader& shader,
                                const std::map<std::string, std::string>& files) {
  std::vector<std::string> out_lines;
  std::stringstream code(shader.code);
  for (std::string line; std::getline(code, line);) out_lines.push_back(line);
  ASSERT_EQ(out_lines.size(), shader.lines.size());
  for (size_t i = 0; i < out_lines.size(); ++i) {
    auto origin = gpu::map_shader_line(shader, uint32_t(i + 1));
    ASSERT_TRUE(origin);
    std::stringstream src(files.at(origin->file));
    std::string line;
    for (uint32_t n = 0; n < origin->line; ++n) std::getline(src, line);
    if (out_lines[i].find("(already included)") != std::string::npos)
      EXPECT_EQ(line.rfind("#include", 0), 0u) << line;
    else
      EXPECT_EQ(out_lines[i], line) << "output line " << i + 1;
  }
}

}  // namespace

TEST(ShaderPreprocessor, NormalisesPaths) {
  EXPECT_EQ(gpu::normalize_shader_path("a/b/../c.wgsl"), "a/c.wgsl");
  EXPECT_EQ(gpu::normalize_shader_path("./a//b.wgsl"), "a/b.wgsl");
  EXPECT_EQ(gpu::normalize_shader_path("../x.wgsl"), "");
}

TEST(ShaderPreprocessor, NestsThreeDeepAndMapsEveryLine) {
  std::map<std::string, std::string> files = {
      {"main.wgsl", "// main\n#include \"a.wgsl\"\nfn main_fn() {}\n"},
      {"a.wgsl", "// a 1\n#include \"b.wgsl\"\n// a 3\n"},
      {"b.wgsl", "// b 1\n  #include \"c.wgsl\"\n// b 3\n"},
      {"c.wgsl", "// c 1\n// c 2"},  // no trailing newline
  };
  auto shader = gpu::preprocess_shader("main.wgsl", gpu::memory_shader_files(files));
  EXPECT_EQ(shader.code,
            "// main\n// a 1\n// b 1\n// c 1\n// c 2\n// b 3\n// a 3\nfn main_fn() {}\n");
  EXPECT_EQ(shader.files, (std::vector<std::string>{"main.wgsl", "a.wgsl", "b.wgsl", "c.wgsl"}));
  std::vector<SourceLocation> expected = {{"main.wgsl", 1}, {"a.wgsl", 1},   {"b.wgsl", 1},
                                          {"c.wgsl", 1},    {"c.wgsl", 2},   {"b.wgsl", 3},
                                          {"a.wgsl", 3},    {"main.wgsl", 3}};
  ASSERT_EQ(shader.lines.size(), expected.size());
  for (uint32_t i = 0; i < expected.size(); ++i)
    EXPECT_EQ(gpu::map_shader_line(shader, i + 1), expected[i]) << "line " << i + 1;
  EXPECT_FALSE(gpu::map_shader_line(shader, 0));
  EXPECT_FALSE(gpu::map_shader_line(shader, 9));
  expect_map_matches_sources(shader, files);
}

TEST(ShaderPreprocessor, IncludesEachFileOnce) {
  std::map<std::string, std::string> files = {
      {"main.wgsl",
       "#include \"a.wgsl\"\n#include \"b.wgsl\"\n#include \"types.wgsl\"\nfn f() {}\n"},
      {"a.wgsl", "#include \"types.wgsl\"\nfn a() {}\n"},
      {"b.wgsl", "#include \"./types.wgsl\"\nfn b() {}\n"},
      {"types.wgsl", "struct T { x: f32 }\n"},
  };
  auto shader = gpu::preprocess_shader("main.wgsl", gpu::memory_shader_files(files));
  size_t first = shader.code.find("struct T");
  ASSERT_NE(first, std::string::npos);
  EXPECT_EQ(shader.code.find("struct T", first + 1), std::string::npos) << shader.code;
  EXPECT_NE(shader.code.find("fn a()"), std::string::npos);
  EXPECT_NE(shader.code.find("fn b()"), std::string::npos);
  expect_map_matches_sources(shader, files);
}

TEST(ShaderPreprocessor, ReportsCyclesWithTheChain) {
  std::map<std::string, std::string> files = {
      {"a.wgsl", "#include \"b.wgsl\"\n"},
      {"b.wgsl", "// b\n#include \"sub/c.wgsl\"\n"},
      {"sub/c.wgsl", "\n\n#include \"../a.wgsl\"\n"},
  };
  std::string message =
      error_of([&] { gpu::preprocess_shader("a.wgsl", gpu::memory_shader_files(files)); });
  EXPECT_NE(message.find("a.wgsl -> b.wgsl -> sub/c.wgsl -> a.wgsl"), std::string::npos) << message;
  EXPECT_NE(message.find("sub/c.wgsl:3"), std::string::npos) << message;
  EXPECT_NE(message.find("cycle"), std::string::npos) << message;

  std::string self = error_of([] {
    gpu::preprocess_shader("x.wgsl", gpu::memory_shader_files({{"x.wgsl", "#include \"x.wgsl\""}}));
  });
  EXPECT_NE(self.find("x.wgsl -> x.wgsl"), std::string::npos) << self;
}

TEST(ShaderPreprocessor, ReportsMissingIncludesWithFileAndLine) {
  std::map<std::string, std::string> files = {
      {"main.wgsl", "#include \"lib/a.wgsl\"\n"},
      {"lib/a.wgsl", "// one\n// two\n#include \"nothere.wgsl\"\n"},
  };
  std::string message =
      error_of([&] { gpu::preprocess_shader("main.wgsl", gpu::memory_shader_files(files)); });
  EXPECT_NE(message.find("lib/a.wgsl:3"), std::string::npos) << message;
  EXPECT_NE(message.find("nothere.wgsl"), std::string::npos) << message;
  EXPECT_NE(message.find("lib/nothere.wgsl"), std::string::npos) << message;  // where it looked

  EXPECT_NE(error_of([] {
              gpu::preprocess_shader("none.wgsl", gpu::memory_shader_files({}));
            }).find("none.wgsl"),
            std::string::npos);
  EXPECT_NE(
      error_of([] {
        gpu::preprocess_shader("m.wgsl", gpu::memory_shader_files({{"m.wgsl", "\n#define X 1\n"}}));
      }).find("m.wgsl:2: unknown preprocessor directive"),
      std::string::npos);
  EXPECT_NE(error_of([] {
              gpu::preprocess_shader("m.wgsl",
                                     gpu::memory_shader_files({{"m.wgsl", "#include <x.wgsl>\n"}}));
            }).find("m.wgsl:1: expected #include"),
            std::string::npos);
}

TEST(ShaderPreprocessor, RelativePathWinsOverSearchPath) {
  std::map<std::string, std::string> files = {
      {"passes/main.wgsl", "#include \"common.wgsl\"\n#include \"only_shared.wgsl\"\n"},
      {"passes/common.wgsl", "// passes/common\n"},
      {"shared/common.wgsl", "// shared/common\n"},
      {"shared/only_shared.wgsl", "// shared/only_shared\n"},
  };
  gpu::PreprocessOptions options;
  options.search_path = {"shared"};
  auto shader =
      gpu::preprocess_shader("passes/main.wgsl", gpu::memory_shader_files(files), options);
  EXPECT_EQ(shader.code, "// passes/common\n// shared/only_shared\n");
  EXPECT_EQ(gpu::map_shader_line(shader, 1), (SourceLocation{"passes/common.wgsl", 1}));
  EXPECT_EQ(gpu::map_shader_line(shader, 2), (SourceLocation{"shared/only_shared.wgsl", 1}));
  // Without the search path the second include is missing.
  EXPECT_NE(error_of([&] {
              gpu::preprocess_shader("passes/main.wgsl", gpu::memory_shader_files(files));
            }).find("passes/main.wgsl:2"),
            std::string::npos);
}

namespace {
// main.wgsl line 1 is a comment, lib/common.wgsl starts at output line 2 (after types.wgsl's 4).
gpu::PreprocessedShader error_shader() {
  return gpu::preprocess_shader(
      "main.wgsl", gpu::memory_shader_files({
                       {"main.wgsl", "// entry\n#include \"lib/common.wgsl\"\nfn main() {}\n"},
                       {"lib/common.wgsl", "#include \"types.wgsl\"\nfn a() {}\nfn b() {}\n"},
                       {"lib/types.wgsl", "struct P {\n  a: f32,\n  b: f32,\n}\n"},
                   }));
}
}  // namespace

TEST(ShaderPreprocessor, MapsTintMessages) {
  auto shader = error_shader();
  // Output: 1 main:1, 2-5 types:1-4, 6 common:2, 7 common:3, 8 main:3.
  ASSERT_EQ(gpu::map_shader_line(shader, 7), (SourceLocation{"lib/common.wgsl", 3}));
  // As Dawn (Tint) prints it on lavapipe.
  std::string tint =
      "Error while parsing WGSL: :7:16 error: unresolved value 'undefined_name'\n"
      "  return p.a + undefined_name;\n"
      "               ^^^^^^^^^^^^^^\n";
  std::string mapped = gpu::map_shader_message(shader, tint);
  EXPECT_NE(mapped.find("WGSL: lib/common.wgsl:3:16 error: unresolved"), std::string::npos)
      << mapped;
  EXPECT_EQ(gpu::map_shader_message(shader, "at :3:1 and :8:2"),
            "at lib/types.wgsl:2:1 and main.wgsl:3:2");
}

TEST(ShaderPreprocessor, MapsNagaMessages) {
  auto shader = error_shader();
  // As wgpu-native (naga, codespan) prints it.
  std::string naga =
      "Shader 'main.wgsl' parsing error: no definition in scope for identifier: `x`\n"
      "  \u250c\u2500 wgsl:7:16\n"
      "  \u2502\n"
      "7 \u2502   return p.a + x;\n"
      "  \u2502                ^ unknown identifier\n";
  std::string mapped = gpu::map_shader_message(shader, naga);
  EXPECT_NE(mapped.find("\u250c\u2500 lib/common.wgsl:3:16\n"), std::string::npos) << mapped;
  EXPECT_NE(mapped.find("\n3 \u2502   return p.a + x;"), std::string::npos) << mapped;
  // Text without locations, times and out-of-range lines stay as they are.
  EXPECT_EQ(gpu::map_shader_message(shader, "at 12:30:45, wgsl:99:1, error: x"),
            "at 12:30:45, wgsl:99:1, error: x");
}

TEST(ShaderPreprocessor, EmbeddedShadersAreFiles) {
  auto text = gpu::embedded_shader_files()("point_draw.wgsl");
  ASSERT_TRUE(text);
  EXPECT_NE(text->find("vs_main"), std::string::npos);
  if (!std::getenv("STIPPLE_SHADER_DIR")) {
    EXPECT_EQ(gpu::shader_source("point_draw.wgsl"), *text);
  }
  EXPECT_FALSE(gpu::embedded_shader_files()("nothing.wgsl"));
  EXPECT_THROW(gpu::shader_source("nothing.wgsl"), Error);
}

TEST(ShaderPreprocessor, DirectoryFilesReadFromDisk) {
  auto files = gpu::directory_shader_files(std::filesystem::path(STIPPLE_SOURCE_DIR) / "shaders");
  auto shader = gpu::preprocess_shader("points.wgsl", files);
  EXPECT_EQ(shader.code.substr(0, 2), "//");
  EXPECT_FALSE(files("missing.wgsl"));
}
