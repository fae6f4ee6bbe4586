#include "stipple/core/progress.hpp"

#include <unistd.h>

#include <cstdio>
#include <cstdlib>

namespace stipple {

Progress::Progress(std::string label, uint64_t total, std::string unit)
    : label_(std::move(label)), unit_(std::move(unit)), total_(total) {
  start_ = last_draw_ = std::chrono::steady_clock::now();
  const char* force = std::getenv("STIPPLE_PROGRESS");
  enabled_ = force ? force[0] == '1' : isatty(STDERR_FILENO) != 0;
}

Progress::~Progress() {
  finish();
}

void Progress::advance(uint64_t n) {
  set(done_ + n);
}

void Progress::set(uint64_t done) {
  done_ = done;
  auto now = std::chrono::steady_clock::now();
  if (enabled_ && now - last_draw_ > std::chrono::milliseconds(100)) {
    last_draw_ = now;
    draw(false);
  }
}

void Progress::finish() {
  if (finished_) return;
  finished_ = true;
  if (enabled_) draw(true);
}

void Progress::draw(bool final) {
  double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start_).count();
  double fraction = total_ ? double(done_) / double(total_) : 1.0;
  if (fraction > 1.0) fraction = 1.0;
  constexpr int width = 30;
  int filled = int(fraction * width);
  char bar[width + 1];
  for (int i = 0; i < width; ++i) bar[i] = i < filled ? '#' : '-';
  bar[width] = 0;
  double rate = seconds > 0 ? double(done_) / seconds : 0.0;
  double eta = rate > 0 && total_ > done_ ? double(total_ - done_) / rate : 0.0;
  const char* scale = "";
  double shown = rate;
  if (shown >= 1e6) {
    shown /= 1e6;
    scale = "M";
  } else if (shown >= 1e3) {
    shown /= 1e3;
    scale = "k";
  }
  std::fprintf(stderr, "\r%s [%s] %5.1f%% %.1f%s %s/s ETA %.0fs%s", label_.c_str(), bar,
               fraction * 100.0, shown, scale, unit_.c_str(), eta, final ? "\n" : "  ");
  std::fflush(stderr);
}

}  // namespace stipple
