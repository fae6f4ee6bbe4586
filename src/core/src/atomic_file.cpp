#include "stipple/core/atomic_file.hpp"

#include <unistd.h>

#include <atomic>
#include <fstream>
#include <string>
#include <system_error>

#include "stipple/core/error.hpp"

namespace stipple {

AtomicFile::AtomicFile(std::filesystem::path target) : target_(std::move(target)) {
  static std::atomic<uint64_t> counter{0};
  const std::filesystem::path folder =
      target_.has_parent_path() ? target_.parent_path() : std::filesystem::path(".");
  std::error_code ec;
  if (!std::filesystem::is_directory(folder, ec))
    fail("{}: cannot write: the folder {} does not exist", target_.string(), folder.string());
  temp_ = target_;
  temp_ += ".partial-" + std::to_string(::getpid()) + "-" + std::to_string(counter++);
}

AtomicFile::~AtomicFile() {
  if (committed_) return;
  std::error_code ec;
  std::filesystem::remove(temp_, ec);
}

void AtomicFile::commit() {
  if (committed_) return;
  std::error_code ec;
  std::filesystem::rename(temp_, target_, ec);
  if (ec) fail("{}: cannot write: {}", target_.string(), ec.message());
  committed_ = true;
}

void write_file_atomically(const std::filesystem::path& path, std::string_view contents) {
  AtomicFile file(path);
  {
    std::ofstream out(file.temp_path(), std::ios::binary);
    out.write(contents.data(), std::streamsize(contents.size()));
    out.close();
    if (!out) fail("{}: cannot write", path.string());
  }
  file.commit();
}

}  // namespace stipple
