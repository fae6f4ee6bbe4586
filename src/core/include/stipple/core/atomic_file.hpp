#pragma once
// Output files appear whole or not at all. An AtomicFile is written under a temporary name in the
// target's own folder ("<name>.partial-<pid>-<n>", so that the final rename stays on one file
// system and is atomic) and renamed over the target by commit(); destroyed without a commit
// (an error, an exception, a killed run's next start aside) it removes the temporary, so a
// failed run leaves neither a truncated file nor a stale temporary behind.
#include <filesystem>
#include <string_view>

namespace stipple {

class AtomicFile {
 public:
  // Throws stipple::Error naming the target when its folder does not exist.
  explicit AtomicFile(std::filesystem::path target);
  ~AtomicFile();
  AtomicFile(const AtomicFile&) = delete;
  AtomicFile& operator=(const AtomicFile&) = delete;

  const std::filesystem::path& target() const { return target_; }
  // Where to write until commit().
  const std::filesystem::path& temp_path() const { return temp_; }
  // Renames the temporary over the target; throws stipple::Error naming the target.
  void commit();
  bool committed() const { return committed_; }

 private:
  std::filesystem::path target_, temp_;
  bool committed_ = false;
};

// Writes `contents` to `path` through an AtomicFile; throws stipple::Error naming the file.
void write_file_atomically(const std::filesystem::path& path, std::string_view contents);

}  // namespace stipple
