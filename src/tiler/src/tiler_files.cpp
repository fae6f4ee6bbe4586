#include "tiler_files.hpp"

#include <fcntl.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <fstream>
#include <utility>

#include "stipple/core/error.hpp"

namespace stipple::tiler::detail {

namespace fs = std::filesystem;

void write_all(int fd, const fs::path& path, const void* data, size_t size) {
  const char* p = static_cast<const char*>(data);
  while (size > 0) {
    ssize_t w = ::write(fd, p, size);
    if (w <= 0) fail("{}: write failed ({})", path.string(), std::strerror(errno));
    p += w, size -= size_t(w);
  }
}

namespace {

// Writes `size` bytes to `path`, truncating (O_TRUNC) or appending (O_APPEND); a failed close
// is a failed write.
void put_file(const fs::path& path, int mode, const void* data, size_t size) {
  FdCloser file{::open(path.c_str(), O_WRONLY | O_CREAT | mode, 0644)};
  if (file.fd < 0) fail("{}: cannot open ({})", path.string(), std::strerror(errno));
  write_all(file.fd, path, data, size);
  if (::close(std::exchange(file.fd, -1)) != 0)
    fail("{}: write failed ({})", path.string(), std::strerror(errno));
}

}  // namespace

void write_file(const fs::path& path, const void* data, size_t size) {
  put_file(path, O_TRUNC, data, size);
}

void append_file(const fs::path& path, const void* data, size_t size) {
  put_file(path, O_APPEND, data, size);
}

void read_points(const fs::path& path, std::vector<TilePoint>& pts) {
  pts.clear();
  std::error_code ec;
  uint64_t size = fs::file_size(path, ec);
  if (ec) return;
  pts.resize(size / sizeof(TilePoint));
  std::ifstream in(path, std::ios::binary);
  in.read(reinterpret_cast<char*>(pts.data()), std::streamsize(pts.size() * sizeof(TilePoint)));
  if (!in) fail("{}: cannot read temporary points", path.string());
}

std::vector<TilePoint> read_points(const fs::path& path) {
  std::vector<TilePoint> pts;
  read_points(path, pts);
  return pts;
}

}  // namespace stipple::tiler::detail
