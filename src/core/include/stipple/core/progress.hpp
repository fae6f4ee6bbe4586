#pragma once
// A terminal progress bar on stderr: fraction, rate and ETA. Silent when stderr is not a
// terminal (CI logs stay readable) unless forced.
#include <chrono>
#include <cstdint>
#include <string>

namespace stipple {

class Progress {
 public:
  Progress(std::string label, uint64_t total, std::string unit = "pts");
  ~Progress();
  Progress(const Progress&) = delete;
  Progress& operator=(const Progress&) = delete;
  void advance(uint64_t n);
  void set(uint64_t done);
  void finish();

 private:
  void draw(bool final);
  std::string label_, unit_;
  uint64_t total_ = 0, done_ = 0;
  std::chrono::steady_clock::time_point start_, last_draw_;
  bool enabled_ = false, finished_ = false;
};

}  // namespace stipple
