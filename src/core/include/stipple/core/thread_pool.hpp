#pragma once
// A fixed-size pool of worker threads with a FIFO queue; parallel_for splits an index range.
#include <condition_variable>
#include <cstddef>
#include <functional>
#include <future>
#include <mutex>
#include <queue>
#include <thread>
#include <vector>

namespace stipple {

class ThreadPool {
 public:
  explicit ThreadPool(unsigned threads = std::thread::hardware_concurrency());
  ~ThreadPool();
  ThreadPool(const ThreadPool&) = delete;
  ThreadPool& operator=(const ThreadPool&) = delete;

  std::future<void> submit(std::function<void()> task);
  // Runs body(begin, end) over [0, count) in pieces of `grain`, on the calling thread and the
  // pool's workers, at most size() at once, and waits; when bodies throw, every piece still ends
  // before the first exception (in time) is rethrown.
  void parallel_for(size_t count, size_t grain, const std::function<void(size_t, size_t)>& body);
  unsigned size() const { return unsigned(workers_.size()); }

 private:
  std::vector<std::thread> workers_;
  std::queue<std::packaged_task<void()>> tasks_;
  std::mutex mutex_;
  std::condition_variable wake_;
  bool stopping_ = false;
};

}  // namespace stipple
