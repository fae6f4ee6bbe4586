// URIs, byte ranges and local files: the parts of io::fetch that need no HTTP client, and fetch()
// itself, which reads URLs through the build's client (detail::perform_http) and fetch_http.
#include <algorithm>
#include <cctype>
#include <cstdio>
#include <filesystem>
#include <fstream>

#include "fetch_detail.hpp"
#include "stipple/core/error.hpp"

namespace stipple::io {
namespace detail {

bool starts_with_ci(std::string_view s, std::string_view prefix) {
  if (s.size() < prefix.size()) return false;
  for (size_t i = 0; i < prefix.size(); ++i)
    if (std::tolower(static_cast<unsigned char>(s[i])) != prefix[i]) return false;
  return true;
}

std::vector<uint8_t> read_file(const std::string& path, const FetchOptions& options) {
  std::error_code ec;
  auto size = std::filesystem::file_size(path, ec);
  if (ec) fail("{}: cannot open ({})", path, ec.message());
  if (size > options.max_bytes)
    fail("{}: {} bytes is more than the limit of {} bytes per file", path, size, options.max_bytes);
  std::ifstream in(path, std::ios::binary);
  if (!in) fail("{}: cannot open", path);
  std::vector<uint8_t> data(size);
  in.read(reinterpret_cast<char*>(data.data()), std::streamsize(size));
  if (in.gcount() != std::streamsize(size)) fail("{}: read error", path);
  return data;
}

std::vector<uint8_t> read_file_range(const std::string& uri, const ByteRange& r,
                                     const FetchOptions& options, FetchStats* stats) {
  const std::string path = uri_path(uri);
  std::error_code ec;
  const uint64_t size = std::filesystem::file_size(path, ec);
  if (ec) fail("{}: cannot open ({})", path, ec.message());
  if (r.size > options.max_bytes)
    fail("{}: a read of {} bytes is more than the limit of {} bytes", path, r.size,
         options.max_bytes);
  if (r.offset > size || r.size > size - r.offset)
    fail("{}: bytes {}-{} are past the end of the file ({} bytes)", path, r.offset,
         r.offset + r.size - 1, size);
  if (stats) {
    stats->attempts = 1;
    stats->total_size = size;
  }
  std::ifstream in(path, std::ios::binary);
  if (!in) fail("{}: cannot open", path);
  std::vector<uint8_t> data(r.size);
  in.seekg(std::streamoff(r.offset));
  in.read(reinterpret_cast<char*>(data.data()), std::streamsize(r.size));
  if (in.gcount() != std::streamsize(r.size)) fail("{}: read error", path);
  return data;
}

}  // namespace detail

using detail::starts_with_ci;

std::vector<uint8_t> fetch(const std::string& uri, const FetchOptions& options, FetchStats* stats) {
  if (!is_url(uri)) {
    ByteRange range;
    if (parse_range_uri(uri, &range)) return detail::read_file_range(uri, range, options, stats);
    if (stats) stats->attempts = 1;
    return detail::read_file(uri.substr(0, uri.find('#')), options);  // fields after '#' are ours
  }
  return fetch_http(http_request(uri, options), detail::perform_http, detail::sleep_ms, stats);
}

std::string range_uri(const std::string& uri, uint64_t offset, uint64_t size) {
  const size_t hash = uri.find('#');
  return fmt::format("{}#bytes={}-{}", uri.substr(0, hash), offset,
                     size > 0 ? offset + size - 1 : offset);
}

std::string fragment_field(const std::string& uri, std::string_view key) {
  const size_t hash = uri.find('#');
  if (hash == std::string::npos) return {};
  std::string_view rest = std::string_view(uri).substr(hash + 1);
  while (!rest.empty()) {
    const size_t amp = rest.find('&');
    std::string_view field = rest.substr(0, amp);
    if (field.size() > key.size() && field.substr(0, key.size()) == key && field[key.size()] == '=')
      return std::string(field.substr(key.size() + 1));
    if (amp == std::string_view::npos) break;
    rest = rest.substr(amp + 1);
  }
  return {};
}

bool parse_range_uri(const std::string& uri, ByteRange* range) {
  const std::string value = fragment_field(uri, "bytes");
  if (value.empty()) return false;
  unsigned long long first = 0, last = 0;
  char tail = 0;
  if (std::sscanf(value.c_str(), "%llu-%llu%c", &first, &last, &tail) != 2 || last < first)
    return false;
  if (range) *range = {first, last - first + 1};
  return true;
}

bool is_url(std::string_view uri) {
  return starts_with_ci(uri, "http://") || starts_with_ci(uri, "https://");
}

std::string uri_path(const std::string& uri) {
  size_t end = uri.find_first_of(is_url(uri) ? "?#" : "#");
  return uri.substr(0, end);
}

std::string resolve_uri(const std::string& base_document, const std::string& relative) {
  if (relative.empty()) return base_document;
  if (is_url(relative) || starts_with_ci(relative, "data:") || relative.front() == '/') {
    // An absolute path on a URL base is relative to the server root.
    if (relative.front() == '/' && is_url(base_document)) {
      size_t scheme = base_document.find("://");
      size_t host_end = base_document.find('/', scheme + 3);
      return base_document.substr(0, host_end) + relative;
    }
    return relative;
  }
  std::string base = uri_path(base_document);
  if (is_url(base)) {
    std::string query;
    size_t q = base_document.find('?');
    // The tileset's query (an API key, a session) is passed on to what it references, as
    // CesiumJS does, unless the reference has its own.
    if (q != std::string::npos && relative.find('?') == std::string::npos)
      query = base_document.substr(q, base_document.find('#', q) - q);
    size_t slash = base.rfind('/');
    std::string dir = base.substr(0, slash + 1);
    // Collapse ./ and ../ segments of the path part.
    size_t scheme = dir.find("://");
    size_t path_start = dir.find('/', scheme + 3);
    if (path_start == std::string::npos) {
      dir += '/';
      path_start = dir.size() - 1;
    }
    std::string root = dir.substr(0, path_start);
    std::vector<std::string> parts;
    std::string path = dir.substr(path_start) + relative;
    size_t end = path.find_first_of("?#");
    std::string tail = end == std::string::npos ? "" : path.substr(end);
    path = path.substr(0, end);
    size_t start = 0;
    while (start <= path.size()) {
      size_t next = path.find('/', start);
      std::string seg =
          path.substr(start, next == std::string::npos ? std::string::npos : next - start);
      if (seg == "..") {
        if (!parts.empty()) parts.pop_back();
      } else if (seg != "." && !(seg.empty() && next != std::string::npos)) {
        parts.push_back(seg);
      }
      if (next == std::string::npos) break;
      start = next + 1;
    }
    std::string out = root;
    for (const auto& p : parts) out += "/" + p;
    return out + tail + (tail.empty() ? query : "");
  }
  std::filesystem::path dir = std::filesystem::path(base).parent_path();
  return (dir / relative).lexically_normal().string();
}

bool looks_like_html(const uint8_t* data, size_t size) {
  size_t i = 0;
  if (size >= 3 && data[0] == 0xEF && data[1] == 0xBB && data[2] == 0xBF) i = 3;
  while (i < size && std::isspace(data[i])) ++i;
  std::string_view head(reinterpret_cast<const char*>(data) + i, std::min<size_t>(size - i, 16));
  return starts_with_ci(head, "<!doctype html") || starts_with_ci(head, "<html") ||
         starts_with_ci(head, "<head") || starts_with_ci(head, "<body");
}

}  // namespace stipple::io
