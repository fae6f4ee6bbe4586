#include "stipple/tiler/profile.hpp"

#include <fcntl.h>
#include <sys/resource.h>
#include <time.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstring>
#include <future>
#include <latch>

#include "stipple/core/thread_pool.hpp"

namespace stipple::tiler {

namespace {

int64_t now_ns(clockid_t clock) {
  timespec ts{};
  if (::clock_gettime(clock, &ts) != 0) return 0;
  return int64_t(ts.tv_sec) * 1'000'000'000 + ts.tv_nsec;
}

double seconds(const timeval& tv) {
  return double(tv.tv_sec) + double(tv.tv_usec) * 1e-6;
}

}  // namespace

const char* step_name(Step s) {
  switch (s) {
    case Step::ReadDecode:
      return "read+decode";
    case Step::Transform:
      return "transform";
    case Step::Count:
      return "count";
    case Step::Distribute:
      return "distribute";
    case Step::Index:
      return "index";
    case Step::Sample:
      return "sample";
    case Step::Encode:
      return "encode";
    case Step::Write:
      return "write";
    case Step::Count_:
      break;
  }
  return "?";
}

Profiler::Profiler() {
  clocks_.push_back(CLOCK_THREAD_CPUTIME_ID);
}

Profiler::~Profiler() {
  stop_ = true;
  if (sampler_.joinable()) sampler_.join();
}

void Profiler::attach(ThreadPool& pool, bool sample) {
  clocks_.clear();
  clockid_t self{};
  clocks_.push_back(
      ::pthread_getcpuclockid(::pthread_self(), &self) == 0 ? self : CLOCK_THREAD_CPUTIME_ID);
  tids_.assign(1, int(::gettid()));
  // One task per worker, each held until every worker took one: each registers once.
  const unsigned n = pool.size();
  std::vector<clockid_t> workers(n);
  std::vector<int> tids(n);
  // Tasks, not parallel_for: its calling thread takes pieces too.
  std::latch all{std::ptrdiff_t(n)};
  std::vector<std::future<void>> registered;
  for (unsigned b = 0; b < n; ++b)
    registered.push_back(pool.submit([&, b] {
      clockid_t c{};
      workers[b] = ::pthread_getcpuclockid(::pthread_self(), &c) == 0 ? c : clockid_t(-1);
      tids[b] = int(::gettid());
      all.arrive_and_wait();
    }));
  for (auto& r : registered) r.get();
  for (size_t i = 0; i < n; ++i)
    if (workers[i] != clockid_t(-1)) clocks_.push_back(workers[i]);
  tids_.insert(tids_.end(), tids.begin(), tids.end());
  if (sample && !sampler_.joinable()) sampler_ = std::thread([this] { sampler(); });
}

Profiler::Snapshot Profiler::snapshot() const {
  Snapshot s;
  s.wall_ns = now_ns(CLOCK_MONOTONIC);
  rusage ru{};
  ::getrusage(RUSAGE_SELF, &ru);
  s.user = seconds(ru.ru_utime), s.sys = seconds(ru.ru_stime);
  s.minflt = uint64_t(ru.ru_minflt), s.majflt = uint64_t(ru.ru_majflt);
  s.nvcsw = uint64_t(ru.ru_nvcsw), s.nivcsw = uint64_t(ru.ru_nivcsw);
  for (clockid_t c : clocks_) s.thread_cpu.push_back(double(now_ns(c)) * 1e-9);
  if (FILE* f = std::fopen("/proc/self/io", "r")) {
    char key[64];
    unsigned long long v = 0;
    while (std::fscanf(f, "%63s %llu", key, &v) == 2) {
      if (std::strcmp(key, "rchar:") == 0) s.rchar = v;
      if (std::strcmp(key, "wchar:") == 0) s.wchar = v;
    }
    std::fclose(f);
  }
  return s;
}

void Profiler::phase(const std::string& name) {
  finish();
  PhaseProfile p;
  p.name = name;
  phases_.push_back(std::move(p));
  {
    std::lock_guard lock(sample_mutex_);
    sampled_one_ = sampled_none_ = 0;
    sampled_since_ns_ = now_ns(CLOCK_MONOTONIC);
  }
  start_ = snapshot();
  open_ = true;
}

void Profiler::finish() {
  if (!open_) return;
  open_ = false;
  const Snapshot end = snapshot();
  PhaseProfile& p = phases_.back();
  p.wall = double(end.wall_ns - start_.wall_ns) * 1e-9;
  p.user = end.user - start_.user, p.sys = end.sys - start_.sys;
  p.thread_cpu.resize(end.thread_cpu.size());
  for (size_t i = 0; i < end.thread_cpu.size() && i < start_.thread_cpu.size(); ++i)
    p.thread_cpu[i] = end.thread_cpu[i] - start_.thread_cpu[i];
  p.bytes_read = end.rchar - start_.rchar, p.bytes_written = end.wchar - start_.wchar;
  p.minor_faults = end.minflt - start_.minflt, p.major_faults = end.majflt - start_.majflt;
  p.voluntary_switches = end.nvcsw - start_.nvcsw;
  p.involuntary_switches = end.nivcsw - start_.nivcsw;
  std::lock_guard lock(sample_mutex_);
  // A sample that ends after the snapshot above belongs to this phase only up to its end.
  p.one_thread = std::min(sampled_one_, p.wall), p.no_thread = std::min(sampled_none_, p.wall);
}

// Every millisecond: how many threads are runnable (state R in /proc/self/task/TID/stat:
// running, or ready and waiting for a core). A thread waiting for a lock, for the disk or for
// work is not; one that other processes keep off the cores is, so that a shared machine's
// load does not read as serial work. The sampler itself is not counted.
void Profiler::sampler() {
  std::vector<int> fds;
  for (int tid : tids_)
    fds.push_back(::open(("/proc/self/task/" + std::to_string(tid) + "/stat").c_str(), O_RDONLY));
  int64_t t0 = now_ns(CLOCK_MONOTONIC);
  char buf[512];
  while (!stop_) {
    std::this_thread::sleep_for(std::chrono::milliseconds(1));
    const int64_t t1 = now_ns(CLOCK_MONOTONIC);
    int running = 0;
    for (int fd : fds) {
      if (fd < 0) continue;
      const ssize_t n = ::pread(fd, buf, sizeof buf - 1, 0);
      if (n <= 0) continue;
      buf[n] = 0;
      // "tid (comm) S ...": the state follows the last ')'.
      const char* close = std::strrchr(buf, ')');
      if (close && close[1] == ' ' && close[2] == 'R') ++running;
    }
    std::lock_guard lock(sample_mutex_);
    // A sampler kept off the cores wakes late: of the time since its last sample, only what
    // lies in the current phase is the phase's.
    const int64_t dt = std::max<int64_t>(0, t1 - std::max(t0, sampled_since_ns_));
    t0 = t1;
    if (running <= 1) sampled_one_ += double(dt) * 1e-9;
    if (running == 0) sampled_none_ += double(dt) * 1e-9;
  }
  for (int fd : fds)
    if (fd >= 0) ::close(fd);
}

StepProfile Profiler::step(Step s) const {
  const size_t i = size_t(s);
  return {double(step_wall_[i].load()) * 1e-9, double(step_cpu_[i].load()) * 1e-9,
          step_bytes_[i].load()};
}

void Profiler::add_step(Step s, double wall, double cpu, uint64_t bytes) {
  const size_t i = size_t(s);
  step_wall_[i] += int64_t(wall * 1e9);
  step_cpu_[i] += int64_t(cpu * 1e9);
  step_bytes_[i] += bytes;
}

Profiler::Scope::Scope(Profiler* p, Step s, uint64_t bytes) : p_(p), s_(s), bytes_(bytes) {
  if (!p_) return;
  wall0_ = now_ns(CLOCK_MONOTONIC);
  cpu0_ = now_ns(CLOCK_THREAD_CPUTIME_ID);
}

Profiler::Scope::~Scope() {
  if (!p_) return;
  const size_t i = size_t(s_);
  p_->step_wall_[i] += now_ns(CLOCK_MONOTONIC) - wall0_;
  p_->step_cpu_[i] += now_ns(CLOCK_THREAD_CPUTIME_ID) - cpu0_;
  p_->step_bytes_[i] += bytes_;
}

}  // namespace stipple::tiler
