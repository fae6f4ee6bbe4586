#pragma once
// Per-phase profile of a tiler run (issue 22): for each phase of the pipeline its wall time,
// the CPU time of every thread (CLOCK_THREAD_CPUTIME_ID through pthread_getcpuclockid), the
// process's user and system time, page faults and context switches (getrusage), the bytes read
// and written (/proc/self/io), and, sampled every millisecond, how long at most one thread ran.
// Inside the phases, the work steps (read+decode, transform, count, distribute, index, sample,
// encode, write) are timed where they run, on whichever thread, so a phase that fuses several
// steps says how its thread time divides.
#include <pthread.h>

#include <array>
#include <atomic>
#include <cstdint>
#include <memory>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

namespace stipple {
class ThreadPool;
}

namespace stipple::tiler {

enum class Step { ReadDecode, Transform, Count, Distribute, Index, Sample, Encode, Write, Count_ };
inline constexpr size_t step_count = size_t(Step::Count_);
const char* step_name(Step s);

struct PhaseProfile {
  std::string name;
  double wall = 0;                 // seconds
  double user = 0, sys = 0;        // process CPU seconds (getrusage, every thread)
  std::vector<double> thread_cpu;  // CPU seconds: [0] the calling thread, then the pool's workers
  uint64_t bytes_read = 0, bytes_written = 0;  // rchar / wchar of /proc/self/io
  uint64_t minor_faults = 0, major_faults = 0;
  uint64_t voluntary_switches = 0, involuntary_switches = 0;
  // Sampled (1 ms): wall seconds in which at most one thread was runnable (running or ready to
  // run), and in which none was (all waiting: for the disk, a lock, work).
  double one_thread = 0, no_thread = 0;
  double cpu() const { return user + sys; }
};

struct StepProfile {
  double thread_seconds = 0;  // wall time spent in the step, summed over threads
  double cpu = 0;             // CPU time in the step, summed over threads
  uint64_t bytes = 0;         // bytes the step decoded (read) or wrote
};

class Profiler {
 public:
  Profiler();
  ~Profiler();
  Profiler(const Profiler&) = delete;
  Profiler& operator=(const Profiler&) = delete;

  // Registers the calling thread and every worker of `pool` (their CPU clocks); with `sample`,
  // starts the 1 ms sampler of how many threads run.
  void attach(ThreadPool& pool, bool sample);
  // Ends the current phase (if any) and starts `name`.
  void phase(const std::string& name);
  // Ends the current phase.
  void finish();
  const std::vector<PhaseProfile>& phases() const { return phases_; }
  StepProfile step(Step s) const;
  void add_step(Step s, double seconds, double cpu, uint64_t bytes);

  // Times one step on the calling thread (steady clock and thread CPU clock).
  class Scope {
   public:
    Scope(Profiler* p, Step s, uint64_t bytes = 0);
    ~Scope();
    void add_bytes(uint64_t b) { bytes_ += b; }
    Scope(const Scope&) = delete;
    Scope& operator=(const Scope&) = delete;

   private:
    Profiler* p_;
    Step s_;
    uint64_t bytes_;
    int64_t wall0_ = 0, cpu0_ = 0;
  };

 private:
  struct Snapshot {
    int64_t wall_ns = 0;
    double user = 0, sys = 0;
    std::vector<double> thread_cpu;
    uint64_t rchar = 0, wchar = 0, minflt = 0, majflt = 0, nvcsw = 0, nivcsw = 0;
  };
  Snapshot snapshot() const;
  void sampler();

  std::vector<clockid_t> clocks_;  // [0] the attaching thread
  std::vector<int> tids_;
  std::vector<PhaseProfile> phases_;
  Snapshot start_;
  bool open_ = false;
  std::mutex sample_mutex_;
  double sampled_one_ = 0, sampled_none_ = 0;  // of the current phase
  int64_t sampled_since_ns_ = 0;  // its start (CLOCK_MONOTONIC): earlier time is not its own
  std::atomic<bool> stop_{false};
  std::thread sampler_;
  std::array<std::atomic<int64_t>, step_count> step_wall_{}, step_cpu_{};
  std::array<std::atomic<uint64_t>, step_count> step_bytes_{};
};

}  // namespace stipple::tiler
