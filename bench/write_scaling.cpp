// How the kernel's cost of writing many tile files grows with the writer threads (issue 22):
// FILES files of SIZE bytes are created and written with T threads, in one directory or
// spread over D subdirectories, and the process's user and system CPU time is printed with the
// wall time. The tiler writes ~5,600 files of ~0.5 MB for 100M points; its `write` step CPU
// grew from 4.6 s at one thread to 21.6 s at 16 on the 16-core machine.
// Build: g++ -O2 -std=c++20 -pthread bench/write_scaling.cpp -o write_scaling
// Run:   write_scaling DIR THREADS [FILES=5600] [SIZE=520000] [SUBDIRS=1] [FSYNC=0]
#include <fcntl.h>
#include <sys/resource.h>
#include <sys/stat.h>
#include <unistd.h>

#include <atomic>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <thread>
#include <vector>

int main(int argc, char** argv) {
  if (argc < 3) {
    std::fprintf(stderr, "usage: %s DIR THREADS [FILES] [SIZE] [SUBDIRS]\n", argv[0]);
    return 2;
  }
  const std::string dir = argv[1];
  const int threads = std::atoi(argv[2]);
  const int files = argc > 3 ? std::atoi(argv[3]) : 5600;
  const size_t size = argc > 4 ? std::strtoull(argv[4], nullptr, 10) : 520000;
  const int subdirs = argc > 5 ? std::atoi(argv[5]) : 1;
  ::mkdir(dir.c_str(), 0755);
  for (int d = 0; d < subdirs; ++d) ::mkdir((dir + "/" + std::to_string(d)).c_str(), 0755);
  std::vector<char> bytes(size, 'x');
  std::atomic<int> next{0};
  auto t0 = std::chrono::steady_clock::now();
  std::vector<std::thread> pool;
  for (int t = 0; t < threads; ++t)
    pool.emplace_back([&] {
      for (int i; (i = next.fetch_add(1)) < files;) {
        std::string path = dir + "/" + std::to_string(i % subdirs) + "/" + std::to_string(i) + ".glb";
        int fd = ::open(path.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
        if (fd < 0 || ::write(fd, bytes.data(), size) != ssize_t(size) || ::close(fd) != 0) {
          std::perror(path.c_str());
          std::exit(1);
        }
      }
    });
  for (auto& t : pool) t.join();
  double wall = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  rusage ru{};
  ::getrusage(RUSAGE_SELF, &ru);
  auto sec = [](timeval v) { return double(v.tv_sec) + double(v.tv_usec) / 1e6; };
  std::printf("threads %2d subdirs %3d files %d x %zu B: wall %.3f s user %.3f s sys %.3f s (%.0f MB/s)\n",
              threads, subdirs, files, size, wall, sec(ru.ru_utime), sec(ru.ru_stime),
              double(files) * double(size) / wall / 1e6);
  return 0;
}
