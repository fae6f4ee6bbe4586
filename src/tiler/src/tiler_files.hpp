#pragma once
// The tiler's file helpers: whole writes and appends with POSIX calls (a failed write or close
// throws, naming the file), and temporary point files read back as TilePoint records. Chunks,
// chunk roots and the staging file are raw records, written and read by every phase. Not part
// of the public API.
#include <unistd.h>

#include <cstddef>
#include <filesystem>
#include <vector>

#include "stipple/tiler/tile_point.hpp"

namespace stipple::tiler::detail {

// Closes a file descriptor when the scope ends, error paths included.
struct FdCloser {
  int fd = -1;
  ~FdCloser() {
    if (fd >= 0) ::close(fd);
  }
};

void write_all(int fd, const std::filesystem::path& path, const void* data, size_t size);
// Writes `size` bytes to `path`, truncating or appending; a failed close is a failed write.
void write_file(const std::filesystem::path& path, const void* data, size_t size);
void append_file(const std::filesystem::path& path, const void* data, size_t size);

// The records of a temporary file (none when it does not exist), into `pts` or a new vector.
void read_points(const std::filesystem::path& path, std::vector<TilePoint>& pts);
std::vector<TilePoint> read_points(const std::filesystem::path& path);

}  // namespace stipple::tiler::detail
