// Compile errors in preprocessed shaders name the original file and line, for both WebGPU
// implementations (Tint and naga format their locations differently).
#include <gtest/gtest.h>

#include "stipple/core/error.hpp"
#include "stipple/renderer/gpu.hpp"
#include "stipple/renderer/shader_preprocessor.hpp"

using namespace stipple;

namespace {

class ShaderErrors : public ::testing::TestWithParam<std::string> {
 protected:
  std::unique_ptr<gpu::Context> context() {
    gpu::ContextOptions options;
    options.backend = GetParam();
    return gpu::create_context(options);
  }
};

gpu::ShaderFiles files() {
  return gpu::memory_shader_files({
      {"main.wgsl",
       "// entry points\n"
       "#include \"lib/common.wgsl\"\n"
       "\n"
       "@compute @workgroup_size(1)\n"
       "fn main() {\n"
       "  _ = helper(1.0);\n"
       "}\n"},
      {"lib/common.wgsl",
       "#include \"types.wgsl\"\n"
       "fn helper(x: f32) -> f32 {\n"
       "  let p = Pair(x, x);\n"
       "  return p.a + undefined_name;\n"
       "}\n"},
      {"lib/types.wgsl", "struct Pair {\n  a: f32,\n  b: f32,\n}\n"},
      {"good.wgsl",
       "#include \"lib/common_ok.wgsl\"\n"
       "@compute @workgroup_size(1)\n"
       "fn main() { _ = twice(1.0); }\n"},
      {"lib/common_ok.wgsl",
       "#include \"types.wgsl\"\n"
       "#include \"types.wgsl\"\n"
       "fn twice(x: f32) -> f32 { let p = Pair(x, x); return p.a + p.b; }\n"},
  });
}

}  // namespace

TEST_P(ShaderErrors, ErrorInIncludedFileNamesThatFileAndLine) {
  auto ctx = context();
  try {
    gpu::create_shader_from_file(*ctx, "main.wgsl", files());
    FAIL() << "expected a compile error";
  } catch (const Error& e) {
    std::string message = e.what();
    // The unresolved identifier is on line 4, column 16 of lib/common.wgsl.
    EXPECT_NE(message.find("lib/common.wgsl:4:"), std::string::npos) << message;
    EXPECT_NE(message.find("main.wgsl"), std::string::npos) << message;
    EXPECT_NE(message.find("undefined_name"), std::string::npos) << message;
  }
}

TEST_P(ShaderErrors, IncludedFilesCompile) {
  auto ctx = context();
  auto module = gpu::create_shader_from_file(*ctx, "good.wgsl", files());
  EXPECT_TRUE(module);
}

TEST_P(ShaderErrors, EmbeddedPointShaderStillCompiles) {
  auto ctx = context();
  auto module = gpu::create_shader_from_file(*ctx, "points.wgsl");
  EXPECT_TRUE(module);
}

INSTANTIATE_TEST_SUITE_P(Backends, ShaderErrors, ::testing::Values("dawn", "wgpu"),
                         [](const auto& info) { return info.param; });
