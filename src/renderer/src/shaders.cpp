#include "stipple/renderer/shaders.hpp"

#include <cstdlib>

#include "stipple/core/error.hpp"
#include "stipple/renderer/shader_preprocessor.hpp"

namespace stipple::gpu {

std::string shader_source(std::string_view name) {
  std::string path = normalize_shader_path(name);
  if (auto text = default_shader_files()(path)) return std::move(*text);
  if (const char* dir = std::getenv("STIPPLE_SHADER_DIR"); dir && *dir)
    fail("{}/{}: cannot read shader (STIPPLE_SHADER_DIR is set)", dir, name);
  fail("no shader named '{}' is embedded", name);
}

}  // namespace stipple::gpu
