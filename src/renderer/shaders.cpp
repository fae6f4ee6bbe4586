#include "renderer/shaders.hpp"

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "core/error.hpp"

namespace stipple::gpu {
namespace detail {
struct EmbeddedShader {
  std::string_view name, source;
};
extern const EmbeddedShader kEmbeddedShaders[];
extern const unsigned kEmbeddedShaderCount;
}  // namespace detail

std::string shader_source(std::string_view name) {
  if (const char* dir = std::getenv("STIPPLE_SHADER_DIR"); dir && *dir) {
    std::filesystem::path path = std::filesystem::path(dir) / std::string(name);
    std::ifstream in(path, std::ios::binary);
    if (!in) fail("{}: cannot read shader (STIPPLE_SHADER_DIR is set)", path.string());
    std::ostringstream text;
    text << in.rdbuf();
    return text.str();
  }
  for (unsigned i = 0; i < detail::kEmbeddedShaderCount; ++i)
    if (detail::kEmbeddedShaders[i].name == name)
      return std::string(detail::kEmbeddedShaders[i].source);
  fail("no shader named '{}' is embedded", name);
}

}  // namespace stipple::gpu
