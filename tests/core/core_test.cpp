// core: atomic output files, medians and the thread pool.
#include <unistd.h>

#include <atomic>
#include <chrono>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <stdexcept>
#include <string>
#include <thread>

#include <gtest/gtest.h>

#include "stipple/core/atomic_file.hpp"
#include "stipple/core/error.hpp"
#include "stipple/core/stats.hpp"
#include "stipple/core/thread_pool.hpp"

using namespace stipple;
namespace fs = std::filesystem;

namespace {

fs::path fresh_dir(const std::string& name) {
  fs::path dir =
      fs::temp_directory_path() / ("stipple-core-" + name + "-" + std::to_string(getpid()));
  fs::remove_all(dir);
  fs::create_directories(dir);
  return dir;
}

std::string read_text(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(in), {});
}

size_t files_in(const fs::path& dir) {
  return size_t(std::distance(fs::directory_iterator(dir), fs::directory_iterator()));
}

}  // namespace

TEST(Median, OddEvenAndEmpty) {
  EXPECT_EQ(median({}), 0.0);
  EXPECT_EQ(median({7.0}), 7.0);
  EXPECT_EQ(median({3.0, 1.0, 2.0}), 2.0);
  EXPECT_EQ(median({4.0, 1.0, 3.0, 2.0}), 2.5);
  EXPECT_EQ(median({5.0, 5.0, 1.0, 9.0, 9.0, 9.0}), 7.0);
}

TEST(AtomicFile, TheTargetAppearsOnlyOnCommit) {
  fs::path dir = fresh_dir("commit");
  fs::path target = dir / "out.txt";
  {
    AtomicFile file(target);
    EXPECT_EQ(file.temp_path().parent_path(), dir);
    std::ofstream(file.temp_path()) << "complete";
    EXPECT_FALSE(fs::exists(target));
    file.commit();
    EXPECT_TRUE(file.committed());
  }
  EXPECT_EQ(read_text(target), "complete");
  EXPECT_EQ(files_in(dir), 1u);  // no temporary left
  fs::remove_all(dir);
}

TEST(AtomicFile, WithoutCommitNothingIsLeft) {
  fs::path dir = fresh_dir("abandon");
  fs::path target = dir / "out.txt";
  std::ofstream(target) << "old";
  try {
    AtomicFile file(target);
    std::ofstream(file.temp_path()) << "half";
    throw std::runtime_error("failed mid-way");
  } catch (const std::runtime_error&) {
  }
  EXPECT_EQ(read_text(target), "old");  // the previous file is untouched
  EXPECT_EQ(files_in(dir), 1u);
  fs::remove_all(dir);
}

TEST(AtomicFile, AMissingFolderIsAClearError) {
  fs::path target = fs::temp_directory_path() / "stipple-no-such-folder" / "x" / "out.json";
  try {
    write_file_atomically(target, "{}");
    FAIL() << "expected an error";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find(target.string()), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("does not exist"), std::string::npos) << e.what();
  }
  EXPECT_FALSE(fs::exists(target));
}

TEST(AtomicFile, WritesWholeContents) {
  fs::path dir = fresh_dir("whole");
  std::string text(100000, 'x');
  write_file_atomically(dir / "big.txt", text);
  EXPECT_EQ(read_text(dir / "big.txt"), text);
  EXPECT_EQ(files_in(dir), 1u);
  fs::remove_all(dir);
}

// A body that throws must not leave the other pieces running on the caller's stack (the tiler's
// workers wrote into freed memory when a progress callback raised): parallel_for rethrows only
// after every piece has ended, and the first exception is the one rethrown.
TEST(ThreadPool, ParallelForEndsEveryPieceBeforeRethrowing) {
  ThreadPool pool(2);
  std::atomic<int> ended{0};
  try {
    pool.parallel_for(8, 1, [&](size_t begin, size_t) {
      if (begin == 0) throw std::runtime_error("piece 0");
      std::this_thread::sleep_for(std::chrono::milliseconds(20));
      ++ended;
    });
    FAIL() << "the exception was swallowed";
  } catch (const std::runtime_error& e) {
    EXPECT_STREQ(e.what(), "piece 0");
  }
  EXPECT_EQ(ended.load(), 7);
}

// The calling thread takes pieces too: every index is covered once, and a parallel_for called
// from the pool's only worker ends (the worker does the pieces itself instead of waiting for a
// task that could never start).
TEST(ThreadPool, ParallelForCoversEachIndexOnceAndNestsOnABusyPool) {
  ThreadPool pool(1);
  std::vector<std::atomic<int>> hits(1001);
  pool.submit([&] {
        pool.parallel_for(hits.size(), 7, [&](size_t begin, size_t end) {
          for (size_t i = begin; i < end; ++i) ++hits[i];
        });
      })
      .get();
  for (size_t i = 0; i < hits.size(); ++i) ASSERT_EQ(hits[i].load(), 1) << "index " << i;
}

// The caller and the workers together run at most size() pieces at once (the tiler's memory
// budgets are per worker).
TEST(ThreadPool, ParallelForRunsAtMostSizePiecesAtOnce) {
  ThreadPool pool(3);
  std::atomic<int> running{0}, most{0};
  pool.parallel_for(24, 1, [&](size_t, size_t) {
    const int now = ++running;
    for (int seen = most.load(); now > seen && !most.compare_exchange_weak(seen, now);) {
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
    --running;
  });
  EXPECT_LE(most.load(), 3);
  EXPECT_GE(most.load(), 2);  // the caller and at least one worker
}
