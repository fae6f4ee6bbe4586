#pragma once
// WGSL has no includes: a small preprocessor resolves `#include "file.wgsl"` over a virtual file
// system (embedded shaders, a directory, or memory in tests) and keeps a line map, so compiler
// messages about the combined source can name the original file and line.
#include <cstdint>
#include <filesystem>
#include <functional>
#include <map>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "stipple/renderer/gpu.hpp"

namespace stipple::gpu {

// Reads a shader by its normalised path ('/'-separated, relative to the shader root, no "." or
// ".." parts); nullopt when there is no such file.
using ShaderFiles = std::function<std::optional<std::string>(const std::string& path)>;

// The shaders embedded at build time (shaders/ and its subfolders).
ShaderFiles embedded_shader_files();
ShaderFiles directory_shader_files(std::filesystem::path root);
ShaderFiles memory_shader_files(std::map<std::string, std::string> files);
// STIPPLE_SHADER_DIR when that is set (edit shaders without rebuilding), else the embedded ones.
ShaderFiles default_shader_files();

struct SourceLocation {
  std::string file;
  uint32_t line = 0;  // 1-based
  bool operator==(const SourceLocation&) const = default;
};

struct PreprocessedShader {
  std::string code;
  std::vector<std::string> files;  // every file that contributed, in order of first inclusion
  struct Line {
    uint32_t file = 0;  // index into files
    uint32_t line = 0;  // 1-based line in that file
  };
  std::vector<Line> lines;  // one per line of code: lines[n - 1] is where output line n came from
};

struct PreprocessOptions {
  // Folders (relative to the shader root) searched after the including file's own folder.
  std::vector<std::string> search_path;
};

// Expands includes starting at `path`. Each file is included once (later includes of the same
// file are dropped, so shared structs are not defined twice). Throws stipple::Error for a missing
// file (naming the including file and line), an include cycle (with the chain) or an unknown
// directive.
PreprocessedShader preprocess_shader(std::string_view path, const ShaderFiles& files,
                                     const PreprocessOptions& options = {});

// Joins and normalises a relative path ("a/b/../c.wgsl" -> "a/c.wgsl"); empty when it climbs out
// of the root.
std::string normalize_shader_path(std::string_view path);

// Where output line `line` (1-based) came from; nullopt when out of range.
std::optional<SourceLocation> map_shader_line(const PreprocessedShader& shader, uint32_t line);

// Rewrites the "line:column" references in a compiler message (Tint's ":12:5 error" and naga's
// "┌─ wgsl:12:5") to "file:line:column" of the original sources.
std::string map_shader_message(const PreprocessedShader& shader, std::string_view message);

// Preprocesses and compiles `path`; compile errors name the original file and line. `trusted`:
// as create_shader's.
ShaderModule create_shader_from_file(Context& ctx, std::string_view path,
                                     const ShaderFiles& files = default_shader_files(),
                                     const PreprocessOptions& options = {}, bool trusted = false);

}  // namespace stipple::gpu
