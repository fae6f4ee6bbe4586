#include "stipple/renderer/shader_preprocessor.hpp"

#include <algorithm>
#include <cstdlib>
#include <fstream>
#include <memory>
#include <set>
#include <sstream>

#include "stipple/core/error.hpp"

namespace stipple::gpu {
namespace detail {
struct EmbeddedShader {
  std::string_view name, source;
};
extern const EmbeddedShader kEmbeddedShaders[];
extern const unsigned kEmbeddedShaderCount;
}  // namespace detail

ShaderFiles embedded_shader_files() {
  return [](const std::string& path) -> std::optional<std::string> {
    for (unsigned i = 0; i < detail::kEmbeddedShaderCount; ++i)
      if (detail::kEmbeddedShaders[i].name == path)
        return std::string(detail::kEmbeddedShaders[i].source);
    return std::nullopt;
  };
}

ShaderFiles directory_shader_files(std::filesystem::path root) {
  return [root = std::move(root)](const std::string& path) -> std::optional<std::string> {
    std::ifstream in(root / path, std::ios::binary);
    if (!in) return std::nullopt;
    std::ostringstream text;
    text << in.rdbuf();
    return text.str();
  };
}

ShaderFiles memory_shader_files(std::map<std::string, std::string> files) {
  // Shared so that copies of the function stay cheap.
  auto table = std::make_shared<const std::map<std::string, std::string>>(std::move(files));
  return [table](const std::string& path) -> std::optional<std::string> {
    auto it = table->find(path);
    if (it == table->end()) return std::nullopt;
    return it->second;
  };
}

ShaderFiles default_shader_files() {
  if (const char* dir = std::getenv("STIPPLE_SHADER_DIR"); dir && *dir)
    return directory_shader_files(dir);
  return embedded_shader_files();
}

std::string normalize_shader_path(std::string_view path) {
  std::vector<std::string_view> parts;
  size_t start = 0;
  while (start <= path.size()) {
    size_t slash = path.find('/', start);
    if (slash == std::string_view::npos) slash = path.size();
    std::string_view part = path.substr(start, slash - start);
    if (part == "..") {
      if (parts.empty()) return {};
      parts.pop_back();
    } else if (!part.empty() && part != ".") {
      parts.push_back(part);
    }
    start = slash + 1;
  }
  std::string out;
  for (std::string_view part : parts) {
    if (!out.empty()) out += '/';
    out += part;
  }
  return out;
}

namespace {

std::string folder_of(const std::string& path) {
  size_t slash = path.rfind('/');
  return slash == std::string::npos ? std::string() : path.substr(0, slash);
}

std::string join(const std::string& folder, std::string_view name) {
  return normalize_shader_path(folder.empty() ? std::string(name)
                                              : folder + "/" + std::string(name));
}

std::vector<std::string_view> split_lines(std::string_view text) {
  std::vector<std::string_view> lines;
  size_t start = 0;
  while (start < text.size()) {
    size_t end = text.find('\n', start);
    if (end == std::string_view::npos) end = text.size();
    std::string_view line = text.substr(start, end - start);
    if (!line.empty() && line.back() == '\r') line.remove_suffix(1);
    lines.push_back(line);
    start = end + 1;
  }
  return lines;
}

std::string_view trim(std::string_view s) {
  while (!s.empty() && (s.front() == ' ' || s.front() == '\t')) s.remove_prefix(1);
  while (!s.empty() && (s.back() == ' ' || s.back() == '\t')) s.remove_suffix(1);
  return s;
}

struct Expander {
  const ShaderFiles& files;
  const PreprocessOptions& options;
  PreprocessedShader out;
  std::set<std::string> included;
  std::vector<std::string> stack;  // files being expanded, outermost first

  uint32_t file_index(const std::string& path) {
    auto it = std::find(out.files.begin(), out.files.end(), path);
    if (it != out.files.end()) return uint32_t(it - out.files.begin());
    out.files.push_back(path);
    return uint32_t(out.files.size() - 1);
  }

  void emit(std::string_view text, uint32_t file, uint32_t line) {
    out.code.append(text);
    out.code += '\n';
    out.lines.push_back({file, line});
  }

  // The included file's path: beside the includer first, then each search folder.
  std::optional<std::pair<std::string, std::string>> resolve(const std::string& includer,
                                                             std::string_view name) {
    std::vector<std::string> candidates = {join(folder_of(includer), name)};
    for (const std::string& folder : options.search_path) candidates.push_back(join(folder, name));
    for (const std::string& candidate : candidates) {
      if (candidate.empty()) continue;
      if (included.count(candidate) || std::count(stack.begin(), stack.end(), candidate))
        return std::pair{candidate, std::string()};  // known: no need to read it again
      if (auto text = files(candidate)) return std::pair{candidate, std::move(*text)};
    }
    return std::nullopt;
  }

  void expand(const std::string& path, const std::string& text) {
    stack.push_back(path);
    included.insert(path);
    uint32_t file = file_index(path);
    auto lines = split_lines(text);
    for (size_t i = 0; i < lines.size(); ++i) {
      uint32_t line_number = uint32_t(i + 1);
      std::string_view line = trim(lines[i]);
      if (line.empty() || line.front() != '#') {
        emit(lines[i], file, line_number);
        continue;
      }
      std::string_view directive = trim(line.substr(1));
      if (directive.substr(0, 7) != "include")
        fail("{}:{}: unknown preprocessor directive '{}'", path, line_number, line);
      std::string_view arg = trim(directive.substr(7));
      if (arg.size() < 2 || arg.front() != '"' || arg.back() != '"')
        fail("{}:{}: expected #include \"file.wgsl\", got '{}'", path, line_number, line);
      std::string_view name = arg.substr(1, arg.size() - 2);
      auto found = resolve(path, name);
      if (!found) {
        std::string looked = join(folder_of(path), name);
        for (const std::string& folder : options.search_path) looked += ", " + join(folder, name);
        fail("{}:{}: cannot find included file \"{}\" (looked for {})", path, line_number, name,
             looked);
      }
      const auto& [resolved, source] = *found;
      if (std::count(stack.begin(), stack.end(), resolved)) {
        std::string chain;
        auto first = std::find(stack.begin(), stack.end(), resolved);
        for (auto it = first; it != stack.end(); ++it) chain += *it + " -> ";
        fail("{}:{}: include cycle: {}{}", path, line_number, chain, resolved);
      }
      if (included.count(resolved)) {
        // Keeps line counts readable in the output and the map complete.
        emit(fmt::format("// #include \"{}\" (already included)", name), file, line_number);
        continue;
      }
      expand(resolved, source);
    }
    stack.pop_back();
  }
};

}  // namespace

PreprocessedShader preprocess_shader(std::string_view path, const ShaderFiles& files,
                                     const PreprocessOptions& options) {
  std::string root = normalize_shader_path(path);
  auto text = root.empty() ? std::nullopt : files(root);
  if (!text) fail("no shader file '{}'", path);
  Expander expander{files, options, {}, {}, {}};
  expander.expand(root, *text);
  return std::move(expander.out);
}

std::optional<SourceLocation> map_shader_line(const PreprocessedShader& shader, uint32_t line) {
  if (line == 0 || line > shader.lines.size()) return std::nullopt;
  const auto& origin = shader.lines[line - 1];
  return SourceLocation{shader.files[origin.file], origin.line};
}

namespace {
bool is_digit(char c) {
  return c >= '0' && c <= '9';
}
bool is_name_char(char c) {
  return is_digit(c) || (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || c == '_' || c == '.' ||
         c == '/' || c == '-';
}
// Parses digits at `pos`; advances it. nullopt when there are none.
std::optional<uint32_t> parse_number(std::string_view s, size_t& pos) {
  size_t start = pos;
  uint64_t value = 0;
  while (pos < s.size() && is_digit(s[pos]) && pos - start < 9)
    value = value * 10 + (s[pos++] - '0');
  if (pos == start) return std::nullopt;
  return uint32_t(value);
}
}  // namespace

namespace {
// naga quotes source lines under a gutter of output line numbers ("8 │   return x;"); they
// become original line numbers.
std::string map_gutter(const PreprocessedShader& shader, std::string_view message) {
  std::string out;
  size_t start = 0;
  while (start < message.size()) {
    size_t end = message.find('\n', start);
    if (end == std::string_view::npos) end = message.size();
    std::string_view line = message.substr(start, end - start);
    size_t pos = 0;
    while (pos < line.size() && line[pos] == ' ') ++pos;
    size_t digits = pos;
    auto number = parse_number(line, pos);
    std::string_view rest = line.substr(pos);
    auto origin = number ? map_shader_line(shader, *number) : std::nullopt;
    if (origin && (rest.starts_with(" \u2502") || rest.starts_with(" |")))
      out += fmt::format("{}{}{}", line.substr(0, digits), origin->line, rest);
    else
      out += line;
    if (end < message.size()) out += '\n';
    start = end + 1;
  }
  return out;
}
}  // namespace

std::string map_shader_message(const PreprocessedShader& shader, std::string_view raw) {
  // Both compilers write a location as "[name]:line:column" (Tint leaves the name empty, naga
  // says "wgsl"); the name is replaced by the original file.
  std::string gutter_mapped = map_gutter(shader, raw);
  std::string_view message = gutter_mapped;
  std::string out;
  size_t i = 0;
  while (i < message.size()) {
    if (message[i] == ':' && (i == 0 || !is_digit(message[i - 1]))) {
      size_t name_start = i;
      while (name_start > 0 && is_name_char(message[name_start - 1])) --name_start;
      size_t pos = i + 1;
      auto line = parse_number(message, pos);
      std::optional<uint32_t> column;
      if (line && pos < message.size() && message[pos] == ':') {
        ++pos;
        column = parse_number(message, pos);
      }
      if (line && column && (pos == message.size() || !is_digit(message[pos]))) {
        if (auto origin = map_shader_line(shader, *line)) {
          out.resize(out.size() - (i - name_start));  // drop the compiler's file name
          out += fmt::format("{}:{}:{}", origin->file, origin->line, *column);
          i = pos;
          continue;
        }
      }
    }
    out += message[i++];
  }
  return out;
}

ShaderModule create_shader_from_file(Context& ctx, std::string_view path, const ShaderFiles& files,
                                     const PreprocessOptions& options, bool trusted) {
  PreprocessedShader shader = preprocess_shader(path, files, options);
  return create_shader(
      ctx, shader.code, path,
      [&](std::string_view message) { return map_shader_message(shader, message); }, trusted);
}

}  // namespace stipple::gpu
