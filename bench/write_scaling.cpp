// How the kernel's cost of writing many tile files grows with the writer threads (issue 22):
// FILES files of SIZE bytes are created and written with T threads, in one directory or
// spread over D subdirectories, and the process's user and system CPU time is printed with the
// wall time. The tiler writes ~5,600 files of ~0.5 MB for 100M points; its `write` step CPU
// grew from 4.6 s at one thread to 21.6 s at 16 on the 16-core machine.
// Build: g++ -O2 -std=c++20 -pthread bench/write_scaling.cpp -o write_scaling
// Run:   write_scaling DIR THREADS [FILES=5600] [SIZE=520000] [SUBDIRS=1] [MODE=buffered]
// MODE: buffered (one write), direct (O_DIRECT from a 4 KiB-aligned buffer, rounded up and
// truncated back), fallocate (blocks reserved, then the buffered write).
#include <fcntl.h>
#include <sys/resource.h>
#include <sys/stat.h>
#include <unistd.h>

#include <atomic>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <string>
#include <thread>
#include <vector>

int main(int argc, char** argv) {
  if (argc < 3) {
    std::fprintf(stderr, "usage: %s DIR THREADS [FILES] [SIZE] [SUBDIRS] [MODE]\n", argv[0]);
    return 2;
  }
  const std::string dir = argv[1];
  const int threads = std::atoi(argv[2]);
  const int files = argc > 3 ? std::atoi(argv[3]) : 5600;
  const size_t size = argc > 4 ? std::strtoull(argv[4], nullptr, 10) : 520000;
  const int subdirs = argc > 5 ? std::atoi(argv[5]) : 1;
  const std::string mode = argc > 6 ? argv[6] : "buffered";
  const bool direct = mode == "direct", reserve = mode == "fallocate";
  if (!direct && !reserve && mode != "buffered") {
    std::fprintf(stderr, "MODE: buffered, direct or fallocate\n");
    return 2;
  }
  const size_t rounded = (size + 4095) & ~size_t(4095);
  ::mkdir(dir.c_str(), 0755);
  for (int d = 0; d < subdirs; ++d) ::mkdir((dir + "/" + std::to_string(d)).c_str(), 0755);
  char* bytes = static_cast<char*>(std::aligned_alloc(4096, rounded));
  std::memset(bytes, 'x', rounded);
  std::atomic<int> next{0};
  auto t0 = std::chrono::steady_clock::now();
  std::vector<std::thread> pool;
  for (int t = 0; t < threads; ++t)
    pool.emplace_back([&] {
      for (int i; (i = next.fetch_add(1)) < files;) {
        std::string path = dir + "/" + std::to_string(i % subdirs) + "/" + std::to_string(i) + ".glb";
        int fd = ::open(path.c_str(), O_WRONLY | O_CREAT | O_TRUNC | (direct ? O_DIRECT : 0), 0644);
        const size_t n = direct ? rounded : size;
        if (fd >= 0 && reserve) (void)::posix_fallocate(fd, 0, off_t(size));
        if (fd < 0 || ::write(fd, bytes, n) != ssize_t(n) ||
            (direct && ::ftruncate(fd, off_t(size)) != 0) || ::close(fd) != 0) {
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
  std::printf("%-9s threads %2d subdirs %3d files %d x %zu B: wall %.3f s user %.3f s sys %.3f s (%.0f MB/s)\n",
              mode.c_str(), threads, subdirs, files, size, wall, sec(ru.ru_utime), sec(ru.ru_stime),
              double(files) * double(size) / wall / 1e6);
  return 0;
}
