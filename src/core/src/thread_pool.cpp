#include "stipple/core/thread_pool.hpp"

#include <algorithm>
#include <atomic>
#include <exception>
#include <memory>

namespace stipple {

ThreadPool::ThreadPool(unsigned threads) {
  threads = std::max(1u, threads);
  for (unsigned i = 0; i < threads; ++i) {
    workers_.emplace_back([this] {
      for (;;) {
        std::packaged_task<void()> task;
        {
          std::unique_lock lock(mutex_);
          wake_.wait(lock, [this] { return stopping_ || !tasks_.empty(); });
          if (stopping_ && tasks_.empty()) return;
          task = std::move(tasks_.front());
          tasks_.pop();
        }
        task();
      }
    });
  }
}

ThreadPool::~ThreadPool() {
  {
    std::lock_guard lock(mutex_);
    stopping_ = true;
  }
  wake_.notify_all();
  for (auto& w : workers_) w.join();
}

std::future<void> ThreadPool::submit(std::function<void()> task) {
  std::packaged_task<void()> packaged(std::move(task));
  auto future = packaged.get_future();
  {
    std::lock_guard lock(mutex_);
    tasks_.push(std::move(packaged));
  }
  wake_.notify_one();
  return future;
}

// The pieces are taken in turn by the calling thread and by up to size() - 1 tasks, so at most
// size() run at once (the tiler's memory budgets count on that). The caller works too: pool
// workers that are busy (or not yet scheduled) delay only the pieces they took, a parallel_for
// inside a task cannot wait on itself, and a task that starts after every piece was taken
// returns at once. The tasks hold the shared state, never the caller's frame.
void ThreadPool::parallel_for(size_t count, size_t grain,
                              const std::function<void(size_t, size_t)>& body) {
  grain = std::max<size_t>(1, grain);
  const size_t pieces = count / grain + (count % grain != 0);
  if (pieces <= 1) {
    if (count > 0) body(0, count);
    return;
  }
  struct Shared {
    std::atomic<size_t> next{0}, done{0};
    size_t pieces = 0, count = 0, grain = 0;
    const std::function<void(size_t, size_t)>* body = nullptr;
    std::mutex mutex;
    std::exception_ptr error;  // the first a piece threw, under mutex
    void work() {
      for (size_t k; (k = next.fetch_add(1)) < pieces;) {
        try {
          (*body)(k * grain, std::min(count, (k + 1) * grain));
        } catch (...) {
          std::lock_guard lock(mutex);
          if (!error) error = std::current_exception();
        }
        if (done.fetch_add(1) + 1 == pieces) done.notify_all();
      }
    }
  };
  auto shared = std::make_shared<Shared>();
  shared->pieces = pieces;
  shared->count = count;
  shared->grain = grain;
  shared->body = &body;
  const size_t helpers = std::min<size_t>(pieces - 1, size() - 1);
  try {
    for (size_t h = 0; h < helpers; ++h) submit([shared] { shared->work(); });
  } catch (...) {
    // Fewer helpers (no memory for a task): the pieces are still all taken, here if need be.
  }
  shared->work();
  // Every piece must end before an exception leaves this frame: they use `body` and what it
  // refers to (the caller's stack).
  for (size_t d; (d = shared->done.load()) < pieces;) shared->done.wait(d);
  if (shared->error) std::rethrow_exception(shared->error);
}

}  // namespace stipple
