// 3D Tiles over HTTP: a local nginx (Debian nginx-light, started by the test on 127.0.0.1 with a
// free port) serves a generated tileset with injected faults: 404, 503 until the file appears
// (retries with back-off), a throttled response, a truncated tile, an HTML page. Loading must
// complete, the good tiles render and each fault is reported for its tile.
#include <arpa/inet.h>
#include <netinet/in.h>
#include <signal.h>
#include <spawn.h>
#include <sys/socket.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <filesystem>
#include <mutex>
#include <thread>

#include <gtest/gtest.h>

#include "stipple/core/error.hpp"
#include "stipple/io/copc.hpp"
#include "stipple/io/fetch.hpp"
#include "stipple/tiles3d/render_load.hpp"
#include "test_util.hpp"
#include "tiles_fixtures.hpp"

extern char** environ;

using namespace stipple;
using namespace stipple::test;
namespace fs = std::filesystem;
using nlohmann::json;

namespace {

int free_port() {
  int s = socket(AF_INET, SOCK_STREAM, 0);
  sockaddr_in a{};
  a.sin_family = AF_INET;
  a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  bind(s, reinterpret_cast<sockaddr*>(&a), sizeof(a));
  socklen_t len = sizeof(a);
  getsockname(s, reinterpret_cast<sockaddr*>(&a), &len);
  close(s);
  return ntohs(a.sin_port);
}

bool can_connect(int port) {
  int s = socket(AF_INET, SOCK_STREAM, 0);
  sockaddr_in a{};
  a.sin_family = AF_INET;
  a.sin_port = htons(uint16_t(port));
  a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  bool ok = connect(s, reinterpret_cast<sockaddr*>(&a), sizeof(a)) == 0;
  close(s);
  return ok;
}

std::string find_nginx() {
  for (const char* p : {"/usr/sbin/nginx", "/usr/bin/nginx"})
    if (fs::exists(p)) return p;
  return "";
}

class Nginx {
 public:
  Nginx(const fs::path& dir, const std::string& binary) : dir_(dir) {
    port_ = free_port();
    fs::create_directories(dir / "tmp");
    std::string d = dir.string();
    std::ofstream(dir / "nginx.conf")
        << "daemon off;\nworker_processes 1;\nerror_log " << d << "/error.log;\npid " << d
        << "/nginx.pid;\nevents { worker_connections 64; }\n"
        << "http {\n access_log off;\n client_body_temp_path " << d << "/tmp;\n proxy_temp_path "
        << d << "/tmp;\n fastcgi_temp_path " << d << "/tmp;\n uwsgi_temp_path " << d
        << "/tmp;\n scgi_temp_path " << d << "/tmp;\n"
        << " types { application/json json; application/octet-stream pnts glb subtree laz; }\n"
        << " gzip on; gzip_types application/json; gzip_min_length 1;\n"
        << " server {\n  listen 127.0.0.1:" << port_ << ";\n  root " << d << "/www;\n"
        << "  location /flaky/ { try_files $uri =503; }\n"
        << "  location /slow/ { limit_rate 16k; }\n"
        << "  location /noranges/ { max_ranges 0; }\n"
        << "  location /html/ { default_type text/html; return 200 "
           "'<html><body>login</body></html>'; }\n"
        << " }\n}\n";
    std::string conf = (dir / "nginx.conf").string(), prefix = d + "/";
    std::vector<char*> argv = {const_cast<char*>(binary.c_str()),
                               const_cast<char*>("-p"),
                               prefix.data(),
                               const_cast<char*>("-c"),
                               conf.data(),
                               nullptr};
    if (posix_spawn(&pid_, binary.c_str(), nullptr, nullptr, argv.data(), environ) != 0) pid_ = -1;
    for (int i = 0; i < 100 && pid_ > 0 && !can_connect(port_); ++i)
      std::this_thread::sleep_for(std::chrono::milliseconds(50));
  }
  ~Nginx() {
    if (pid_ > 0) {
      kill(pid_, SIGTERM);
      int status = 0;
      waitpid(pid_, &status, 0);
    }
  }
  bool running() const { return pid_ > 0 && can_connect(port_); }
  std::string url(const std::string& path) const {
    return "http://127.0.0.1:" + std::to_string(port_) + "/" + path;
  }

 private:
  fs::path dir_;
  int port_ = 0;
  pid_t pid_ = -1;
};

json leaf(double x, const std::string& uri) {
  return {{"boundingVolume", {{"box", {x + 5, 5, 5, 5, 0, 0, 0, 5, 0, 0, 0, 5}}}},
          {"geometricError", 0},
          {"content", {{"uri", uri}}}};
}

}  // namespace

TEST(TilesHttp, FaultsAreReportedPerTileAndLoadingCompletes) {
  std::string nginx = find_nginx();
  if (nginx.empty()) GTEST_SKIP() << "nginx not installed (Debian nginx-light): HTTP tests skipped";
  fs::path dir = fs::temp_directory_path() / ("stipple-http-" + std::to_string(::getpid()));
  fs::remove_all(dir);
  fs::path www = dir / "www";
  double rtc[3] = {0, 0, 0};
  Bytes good = grid_pnts(300, 10.0f, rtc, 100);
  Bytes big = grid_pnts(6000, 10.0f, rtc, 50);  // ~90 KB at 16 KB/s: several seconds
  write_file(www / "t/good.pnts", good);
  write_file(www / "slow/t/slow.pnts", big);
  Bytes truncated(good.begin(), good.begin() + std::ptrdiff_t(good.size() / 2));
  write_file(www / "t/truncated.pnts", truncated);
  json root = {
      {"boundingVolume", {{"box", {30, 5, 5, 30, 0, 0, 0, 5, 0, 0, 0, 5}}}},
      {"geometricError", 1e6},
      {"refine", "ADD"},
      {"children",
       {leaf(0, "t/good.pnts"), leaf(10, "missing.pnts"), leaf(20, "flaky/late.pnts"),
        leaf(30, "slow/t/slow.pnts"), leaf(40, "t/truncated.pnts"), leaf(50, "html/x.pnts")}}};
  write_json(www / "tileset.json",
             {{"asset", {{"version", "1.1"}}}, {"geometricError", 1e6}, {"root", root}});
  Nginx server(dir, nginx);
  ASSERT_TRUE(server.running()) << "nginx did not start; see " << (dir / "error.log");

  // The flaky tile appears 0.5 s in: the first tries get 503, a retry succeeds.
  std::thread late([&] {
    std::this_thread::sleep_for(std::chrono::milliseconds(500));
    write_file(www / "flaky/late.pnts", good);
  });
  tiles3d::RenderLoadOptions opt;
  opt.streamer.fetch.max_retries = 5;
  opt.streamer.fetch.backoff_initial_ms = 100;
  opt.streamer.fetch.low_speed_bytes = 1000;
  opt.streamer.fetch.low_speed_time_s = 5;
  opt.streamer.traversal.max_sse = 1e-9;  // everything
  auto r = tiles3d::load_tileset_for_render(server.url("tileset.json"), opt);
  late.join();
  EXPECT_EQ(r.tiles_rendered, 3u);  // good, flaky, slow
  EXPECT_EQ(r.cloud.point_count, 300u + 300u + 6000u);
  std::string all;
  for (const auto& e : r.errors) all += e.message + "\n";
  EXPECT_EQ(r.errors.size(), 3u) << all;
  EXPECT_NE(all.find("HTTP 404"), std::string::npos) << all;
  EXPECT_NE(all.find("HTML"), std::string::npos) << all;
  EXPECT_NE(all.find("truncated"), std::string::npos) << all;

  // Fetch directly: 4xx is not retried; gzip is accepted; the size cap holds.
  io::FetchStats stats;
  EXPECT_THROW(io::fetch(server.url("nothing.json"), {}, &stats), Error);
  EXPECT_EQ(stats.attempts, 1);
  auto body = io::fetch(server.url("tileset.json"));
  EXPECT_EQ(body.front(), '{');
  io::FetchOptions small;
  small.max_bytes = 1000;
  EXPECT_THROW(io::fetch(server.url("slow/t/slow.pnts"), small), Error);
  // A stalled server (far below the low-speed limit) times out instead of hanging.
  io::FetchOptions impatient;
  impatient.low_speed_bytes = 1'000'000;
  impatient.low_speed_time_s = 1;
  impatient.max_retries = 1;
  impatient.backoff_initial_ms = 10;
  EXPECT_THROW(io::fetch(server.url("slow/t/slow.pnts"), impatient), Error);
  fs::remove_all(dir);
}

TEST(TilesHttp, ResolvesRelativeUris) {
  EXPECT_EQ(io::resolve_uri("http://h:1/a/b/tileset.json", "../c/d.pnts"), "http://h:1/a/c/d.pnts");
  EXPECT_EQ(io::resolve_uri("http://h/a/tileset.json?key=1", "x.pnts"), "http://h/a/x.pnts?key=1");
  EXPECT_EQ(io::resolve_uri("http://h/a/tileset.json", "/root.json"), "http://h/root.json");
  EXPECT_EQ(io::resolve_uri("/data/t/tileset.json", "./sub/../x.glb"), "/data/t/x.glb");
  EXPECT_EQ(io::resolve_uri("/data/t/tileset.json", "https://o/x.glb"), "https://o/x.glb");
}

// COPC over HTTP: the header, every hierarchy page and every node are byte-range requests (206),
// and the streamed points are the file's; a server that ignores ranges is a clear error.
TEST(TilesHttp, CopcIsStreamedByRangeRequests) {
  std::string nginx = find_nginx();
  if (nginx.empty()) GTEST_SKIP() << "nginx not installed (Debian nginx-light): HTTP tests skipped";
  STIPPLE_REQUIRE_DATA(copc, "laz/lone-star.copc.laz");
  fs::path dir = fs::temp_directory_path() / ("stipple-http-copc-" + std::to_string(::getpid()));
  fs::remove_all(dir);
  fs::create_directories(dir / "www/data");
  fs::create_directories(dir / "www/noranges");
  fs::copy_file(copc, dir / "www/data/lone-star.copc.laz");
  fs::copy_file(copc, dir / "www/noranges/lone-star.copc.laz");
  Nginx server(dir, nginx);
  ASSERT_TRUE(server.running()) << "nginx did not start; see " << (dir / "error.log");

  const std::string url = server.url("data/lone-star.copc.laz");
  ASSERT_TRUE(io::is_copc_input(url));
  std::mutex mutex;
  std::vector<std::string> requests;
  tiles3d::RenderLoadOptions opt;
  opt.streamer.fetcher = [&](const std::string& uri) {
    {
      std::lock_guard lock(mutex);
      requests.push_back(uri);
    }
    io::FetchStats stats;
    auto bytes = io::fetch(uri, {}, &stats);
    EXPECT_EQ(stats.http_status, 206) << uri;
    EXPECT_EQ(stats.total_size, fs::file_size(copc)) << uri;
    return bytes;
  };
  opt.streamer.traversal.max_sse = 1e-9;  // every node
  auto r = tiles3d::load_tileset_for_render(url, opt);
  EXPECT_EQ(r.cloud.point_count, 518862u);
  EXPECT_EQ(r.tiles_rendered, 15u);
  EXPECT_TRUE(r.errors.empty());
  // The header, the header with its VLRs, the root page, then the 15 nodes once each.
  ASSERT_EQ(requests.size(), 18u);
  for (const auto& u : requests) EXPECT_NE(u.find("#bytes="), std::string::npos) << u;

  // max_ranges 0: nginx answers 200 with the whole file.
  try {
    io::load_tileset(server.url("noranges/lone-star.copc.laz"));
    ADD_FAILURE() << "a server ignoring ranges was not reported";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("ignores range requests"), std::string::npos) << e.what();
  }
  fs::remove_all(dir);
}
