// The splat tiler's pipeline (splat_tiler.hpp): stage, count, chunk, build each chunk's
// subtree, build the levels above the chunks, write tileset.json, commit.
#include "stipple/tiler/splat_tiler.hpp"

#include <stdlib.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <chrono>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <sstream>
#include <thread>

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include "stipple/core/error.hpp"
#include "stipple/core/log.hpp"
#include "stipple/core/thread_pool.hpp"
#include "stipple/io/splat_readers.hpp"
#include "stipple/tiler/splat_merge.hpp"
#include "stipple/tiler/tile_point.hpp"
#include "tiler_files.hpp"

namespace stipple::tiler {

namespace {

namespace fs = std::filesystem;
using detail::append_file;
using detail::write_file;

constexpr int kMaxLevel = 20;
constexpr int kCountLevel = 6;  // the counting grid: 64^3 cells

struct Key {
  int level = 0;
  uint32_t x = 0, y = 0, z = 0;
  auto operator<=>(const Key&) const = default;
  Key child(int i) const {
    return {level + 1, 2 * x + (i & 1), 2 * y + ((i >> 1) & 1), 2 * z + ((i >> 2) & 1)};
  }
  Key parent() const { return {level - 1, x / 2, y / 2, z / 2}; }
  std::string name() const { return fmt::format("{}-{}-{}-{}", level, x, y, z); }
};

// A splat as a record of floats: position, scale, rotation (x, y, z, w), opacity, SH DC, then
// the higher SH coefficients.
struct Layout {
  int degree = 0;
  size_t rest = 0, stride = 14;
  explicit Layout(int d = 0)
      : degree(d), rest(size_t((d + 1) * (d + 1) - 1)), stride(14 + 3 * rest) {}
};

void to_records(const io::SplatSet& s, size_t begin, size_t end, const Layout& l, float* out) {
  for (size_t i = begin; i < end; ++i, out += l.stride) {
    std::memcpy(out, &s.positions[i], 12);
    std::memcpy(out + 3, &s.scales[i], 12);
    std::memcpy(out + 6, &s.rotations[i], 16);
    out[10] = s.opacities[i];
    std::memcpy(out + 11, &s.sh_dc[i], 12);
    if (l.rest) std::memcpy(out + 14, &s.sh_rest[i * l.rest], l.rest * 12);
  }
}

io::SplatSet from_records(const float* in, size_t n, const Layout& l) {
  io::SplatSet s;
  s.sh_degree = l.degree;
  s.positions.resize(n);
  s.scales.resize(n);
  s.rotations.resize(n);
  s.opacities.resize(n);
  s.sh_dc.resize(n);
  s.sh_rest.resize(n * l.rest);
  for (size_t i = 0; i < n; ++i, in += l.stride) {
    std::memcpy(&s.positions[i], in, 12);
    std::memcpy(&s.scales[i], in + 3, 12);
    std::memcpy(&s.rotations[i], in + 6, 16);
    s.opacities[i] = in[10];
    std::memcpy(&s.sh_dc[i], in + 11, 12);
    if (l.rest) std::memcpy(&s.sh_rest[i * l.rest], in + 14, l.rest * 12);
  }
  return s;
}

// The records of a file (`stride` floats each).
std::vector<float> read_records(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) fail("{}: cannot open a temporary splat file", path.string());
  const uint64_t size = fs::file_size(path);
  std::vector<float> out(size_t(size / 4));
  in.read(reinterpret_cast<char*>(out.data()), std::streamsize(out.size() * 4));
  if (uint64_t(in.gcount()) != out.size() * 4)
    fail("{}: cannot read a temporary splat file", path.string());
  return out;
}

// Reads a file of records block by block: body(records, count).
template <typename Body>
void for_each_block(const fs::path& path, const Layout& l, size_t block, Body body) {
  std::ifstream in(path, std::ios::binary);
  if (!in) fail("{}: cannot open a temporary splat file", path.string());
  std::vector<float> buf(block * l.stride);
  while (in) {
    in.read(reinterpret_cast<char*>(buf.data()), std::streamsize(buf.size() * 4));
    const size_t n = size_t(in.gcount()) / 4 / l.stride;
    if (n) body(buf.data(), n);
  }
}

struct NodeOut {
  Box bounds;  // Y-up, the splats' 3-sigma extents
  uint64_t splats = 0;
  double error = 0;
  bool leaf = false;
};

struct ChunkFile {
  Key key;
  uint64_t count = 0;
  fs::path file;
  std::vector<float> pending;
};

// Removes the partial output unless the run commits.
struct Partial {
  fs::path path;
  bool committed = false;
  ~Partial() {
    if (!committed && !path.empty()) {
      std::error_code ec;
      fs::remove_all(path, ec);
    }
  }
};

struct SplatBuild {
  explicit SplatBuild(const SplatTileOptions& o) : opt(o) {}
  const SplatTileOptions& opt;
  Layout lay;
  glm::dmat4 transform{1.0};
  std::string format;
  Partial partial;
  fs::path dir, tmp;
  glm::dvec3 cube_min{0};
  double cube_size = 1;
  uint64_t total = 0;
  size_t chunk_cap = 0;
  std::unique_ptr<ThreadPool> pool;
  std::vector<std::unique_ptr<ChunkFile>> chunks;
  std::mutex mutex;  // nodes, pending
  std::map<Key, NodeOut> nodes;
  std::map<Key, fs::path> pending;  // chunk roots and upper nodes: their representation
  std::atomic<uint64_t> leaf_splats{0}, merged_splats{0}, bytes{0};

  double node_size(int level) const { return cube_size / double(uint64_t(1) << level); }
  glm::dvec3 node_min(const Key& k) const {
    return cube_min + glm::dvec3(k.x, k.y, k.z) * node_size(k.level);
  }
};

// The largest scale times three: the extent the renderer draws of a splat.
Box extent_of(const io::SplatSet& s) {
  Box b;
  for (size_t i = 0; i < s.size(); ++i) {
    const glm::vec3& sc = s.scales[i];
    const double r = 3.0 * double(std::max({sc.x, sc.y, sc.z}));
    b.add(glm::dvec3(s.positions[i]) - r);
    b.add(glm::dvec3(s.positions[i]) + r);
  }
  return b;
}

void write_tile(SplatBuild& b, const Key& k, const io::SplatSet& s, bool leaf, double error) {
  const std::vector<uint8_t> glb = write_splat_glb(morton_sorted(s), b.opt.compression);
  write_file(b.dir / "tiles" / (k.name() + ".glb"), glb.data(), glb.size());
  b.bytes += glb.size();
  (leaf ? b.leaf_splats : b.merged_splats) += s.size();
  NodeOut out;
  out.bounds = extent_of(s);
  out.splats = s.size();
  out.error = error;
  out.leaf = leaf;
  std::lock_guard lock(b.mutex);
  b.nodes[k] = out;
}

double error_of(SplatBuild& b, const Key& k) {
  std::lock_guard lock(b.mutex);
  return b.nodes.at(k).error;
}

// The merged representation of the union of the children's splats.
io::SplatSet merge_node(SplatBuild& b, const Key& k, const io::SplatSet& children,
                        double child_error) {
  const size_t target = std::min<size_t>(
      b.opt.max_leaf_splats,
      std::max<size_t>(1, size_t(double(children.size()) / std::max(1.0, b.opt.merge_ratio))));
  MergeResult m = merge_splats(children, b.node_min(k), b.node_size(k.level), target);
  write_tile(b, k, m.splats, false, std::max(m.cell_size, child_error));
  return std::move(m.splats);
}

// A node over records [recs, recs + n * stride): a leaf when small enough, else the records are
// partitioned into the 8 children (through `scratch`) and the node merges their results.
// Returns the node's splats (the leaf's own, or the merge).
io::SplatSet build_node(SplatBuild& b, const Key& k, float* recs, size_t n,
                        std::vector<float>& scratch) {
  const Layout& l = b.lay;
  if (n <= b.opt.max_leaf_splats || k.level >= kMaxLevel) {
    io::SplatSet s = from_records(recs, n, l);
    write_tile(b, k, s, true, 0.0);
    return s;
  }
  const glm::dvec3 centre = b.node_min(k) + glm::dvec3(b.node_size(k.level + 1));
  auto octant = [&](const float* r) {
    return int(double(r[0]) >= centre.x) | int(double(r[1]) >= centre.y) << 1 |
           int(double(r[2]) >= centre.z) << 2;
  };
  size_t count[8] = {}, offset[9] = {};
  for (size_t i = 0; i < n; ++i) ++count[octant(recs + i * l.stride)];
  for (int c = 0; c < 8; ++c) offset[c + 1] = offset[c] + count[c];
  scratch.resize(std::max(scratch.size(), n * l.stride));
  size_t fill[8];
  std::copy(offset, offset + 8, fill);
  for (size_t i = 0; i < n; ++i) {
    const float* r = recs + i * l.stride;
    std::memcpy(scratch.data() + fill[octant(r)]++ * l.stride, r, l.stride * 4);
  }
  std::memcpy(recs, scratch.data(), n * l.stride * 4);
  io::SplatSet children;
  children.sh_degree = l.degree;
  double child_error = 0;
  for (int c = 0; c < 8; ++c) {
    if (!count[c]) continue;
    const Key ck = k.child(c);
    io::append_splats(children, build_node(b, ck, recs + offset[c] * l.stride, count[c], scratch));
    child_error = std::max(child_error, error_of(b, ck));
  }
  return merge_node(b, k, children, child_error);
}

fs::path begin_output(SplatBuild& b) {
  fs::path out = fs::absolute(b.opt.output).lexically_normal();
  if (out.filename().empty()) out = out.parent_path();
  if (fs::exists(out) && !b.opt.force) fail("{} exists; pass --force to replace it", out.string());
  const fs::path parent = out.parent_path();
  if (!fs::is_directory(parent)) fail("{}: no such directory", parent.string());
  std::string templ = (parent / (out.filename().string() + ".partial-XXXXXX")).string();
  if (!::mkdtemp(templ.data()))
    fail("cannot create a directory beside {} ({})", out.string(), std::strerror(errno));
  b.partial.path = templ;
  b.dir = templ;
  b.tmp = b.dir / ".tmp";
  fs::create_directories(b.tmp);
  fs::create_directories(b.dir / "tiles");
  return out;
}

// An INRIA PLY on disk read in blocks of `block` splats, each decoded by the PLY reader (the
// header with the block's count, then the block's records), so that a large trained scene never
// sits in memory whole. Returns false, having read nothing, for anything else (URLs, other
// layouts: PlayCanvas's compressed PLY, ASCII, several elements, list properties).
bool stream_inria_ply(const std::string& path, size_t block,
                      const std::function<void(io::SplatSet&&)>& sink) {
  if (!fs::is_regular_file(path)) return false;
  std::ifstream in(path, std::ios::binary);
  std::string head(65536, '\0');
  in.read(head.data(), std::streamsize(head.size()));
  head.resize(size_t(in.gcount()));
  if (!head.starts_with("ply")) return false;
  const size_t end = head.find("end_header\n");
  if (end == std::string::npos) return false;
  const std::string header = head.substr(0, end + 11);
  std::istringstream lines(header);
  std::string line, before, after;
  uint64_t count = 0;
  size_t stride = 0, elements = 0;
  bool binary = false, inria = false, counted = false;
  while (std::getline(lines, line)) {
    if (!line.empty() && line.back() == '\r') return false;  // keep to the plain layout
    std::istringstream words(line);
    std::string w0, w1, w2;
    words >> w0 >> w1 >> w2;
    if (w0 == "format") binary = w1 == "binary_little_endian";
    if (w0 == "element") {
      if (++elements > 1 || w1 != "vertex") return false;
      try {
        count = std::stoull(w2);
      } catch (const std::exception&) {
        return false;
      }
      counted = true;
      continue;
    }
    if (w0 == "property") {
      static const std::map<std::string, size_t> sizes = {
          {"char", 1},  {"uchar", 1},   {"int8", 1},   {"uint8", 1},  {"short", 2}, {"ushort", 2},
          {"int16", 2}, {"uint16", 2},  {"int", 4},    {"uint", 4},   {"int32", 4}, {"uint32", 4},
          {"float", 4}, {"float32", 4}, {"double", 8}, {"float64", 8}};
      const auto it = sizes.find(w1);
      if (it == sizes.end()) return false;  // a list, or a type this path does not know
      stride += it->second;
      inria = inria || w2 == "f_dc_0";
    }
    (counted ? after : before) += line + "\n";
  }
  if (!binary || !inria || !counted || stride == 0) return false;
  // `before` ends before the element line, `after` holds the properties and end_header.
  in.clear();
  in.seekg(std::streamoff(header.size()));
  std::vector<char> bytes;
  for (uint64_t first = 0; first < count; first += block) {
    const size_t n = size_t(std::min<uint64_t>(block, count - first));
    const std::string h = before + fmt::format("element vertex {}\n", n) + after;
    bytes.assign(h.begin(), h.end());
    bytes.resize(h.size() + n * stride);
    in.read(bytes.data() + h.size(), std::streamsize(n * stride));
    if (size_t(in.gcount()) != n * stride)
      fail("{}: PLY element vertex ({} records of {} bytes) runs past the end of the file", path,
           count, stride);
    sink(io::decode_splats(std::span(reinterpret_cast<const uint8_t*>(bytes.data()), bytes.size()),
                           path));
  }
  return true;
}

// Every input decoded in turn, appended to the staging file; returns its bounds (centres).
Box stage_inputs(SplatBuild& b, const fs::path& staged) {
  Box box;
  bool first = true;
  // INRIA PLY files are read in blocks of about a sixteenth of the budget (their records and the
  // decoded set); other formats whole.
  const size_t block = size_t(std::max<uint64_t>(b.opt.max_memory / 16 / 512, 4096));
  for (const std::string& path : b.opt.inputs) {
    uint64_t before = b.total;
    auto stage = [&](io::SplatSet&& s) {
      if (first) {
        b.lay = Layout(s.sh_degree);
        b.transform = s.transform;
        b.format = s.format;
        first = false;
      } else {
        if (s.sh_degree != b.lay.degree)
          fail("{}: SH degree {} differs from the first input's {}; tile them separately", path,
               s.sh_degree, b.lay.degree);
        if (s.transform != b.transform)
          fail("{}: its frame ({}) differs from the first input's; tile them separately", path,
               s.format);
      }
      for (const glm::vec3& p : s.positions) box.add(glm::dvec3(p));
      const size_t records = 65536;
      std::vector<float> recs(records * b.lay.stride);
      for (size_t at = 0; at < s.size(); at += records) {
        const size_t e = std::min(s.size(), at + records);
        to_records(s, at, e, b.lay, recs.data());
        append_file(staged, recs.data(), (e - at) * b.lay.stride * 4);
      }
      b.total += s.size();
    };
    if (!stream_inria_ply(path, block, stage)) stage(io::read_splats(path));
    STIPPLE_INFO("tile: {}: {} splats, SH degree {}, {}", path, b.total - before, b.lay.degree,
                 b.format);
  }
  if (b.total == 0) fail("the inputs hold no splats");
  return box;
}

int cell_axis(const SplatBuild& b, double v, int k, int level) {
  const double cells = double(1u << level);
  const double g = std::clamp((v - b.cube_min[k]) / b.cube_size * cells, 0.0, cells - 1);
  return int(g);
}

// The count grid cut into the largest nodes of at most chunk_cap splats; the staged records
// appended to one file a chunk.
void make_chunks(SplatBuild& b, const fs::path& staged) {
  const Layout& l = b.lay;
  if (b.total <= b.chunk_cap) {
    auto c = std::make_unique<ChunkFile>();
    c->count = b.total;
    c->file = staged;
    b.chunks.push_back(std::move(c));
    return;
  }
  const uint32_t n = 1u << kCountLevel;
  auto cell_of = [&](const float* r) {
    return (size_t(cell_axis(b, r[2], 2, kCountLevel)) * n +
            size_t(cell_axis(b, r[1], 1, kCountLevel))) *
               n +
           size_t(cell_axis(b, r[0], 0, kCountLevel));
  };
  std::vector<std::vector<uint64_t>> pyramid(kCountLevel + 1);
  pyramid[kCountLevel].assign(size_t(n) * n * n, 0);
  for_each_block(staged, l, 65536, [&](const float* r, size_t count) {
    for (size_t i = 0; i < count; ++i) ++pyramid[kCountLevel][cell_of(r + i * l.stride)];
  });
  for (int lv = kCountLevel - 1; lv >= 0; --lv) {
    const uint32_t m = 1u << lv;
    pyramid[size_t(lv)].assign(size_t(m) * m * m, 0);
    for (uint32_t z = 0; z < 2 * m; ++z)
      for (uint32_t y = 0; y < 2 * m; ++y)
        for (uint32_t x = 0; x < 2 * m; ++x)
          pyramid[size_t(lv)][(size_t(z / 2) * m + y / 2) * m + x / 2] +=
              pyramid[size_t(lv) + 1][(size_t(z) * 2 * m + y) * 2 * m + x];
  }
  std::vector<int32_t> cell_chunk(size_t(n) * n * n, -1);
  std::vector<Key> stack{Key{}};
  while (!stack.empty()) {
    const Key k = stack.back();
    stack.pop_back();
    const uint32_t m = 1u << k.level;
    const uint64_t c = pyramid[size_t(k.level)][(size_t(k.z) * m + k.y) * m + k.x];
    if (c == 0) continue;
    if (c > b.chunk_cap && k.level < kCountLevel) {
      for (int i = 0; i < 8; ++i) stack.push_back(k.child(i));
      continue;
    }
    const int shift = kCountLevel - k.level;
    const uint32_t span = 1u << shift;
    for (uint32_t z = 0; z < span; ++z)
      for (uint32_t y = 0; y < span; ++y)
        for (uint32_t x = 0; x < span; ++x)
          cell_chunk[(size_t((k.z << shift) + z) * n + ((k.y << shift) + y)) * n +
                     ((k.x << shift) + x)] = int32_t(b.chunks.size());
    auto chunk = std::make_unique<ChunkFile>();
    chunk->key = k;
    chunk->file = b.tmp / ("chunk-" + k.name() + ".bin");
    b.chunks.push_back(std::move(chunk));
  }
  // Buffers of together about a sixteenth of the budget, at least 64 KiB each.
  const size_t buffer_floats = std::max<size_t>(
      16384, size_t(b.opt.max_memory / 16 / 4 / std::max<size_t>(1, b.chunks.size())));
  for_each_block(staged, l, 65536, [&](const float* r, size_t count) {
    for (size_t i = 0; i < count; ++i) {
      const float* rec = r + i * l.stride;
      ChunkFile& c = *b.chunks[size_t(cell_chunk[cell_of(rec)])];
      c.pending.insert(c.pending.end(), rec, rec + l.stride);
      ++c.count;
      if (c.pending.size() >= buffer_floats) {
        append_file(c.file, c.pending.data(), c.pending.size() * 4);
        c.pending.clear();
      }
    }
  });
  for (auto& c : b.chunks) {
    if (!c->pending.empty()) append_file(c->file, c->pending.data(), c->pending.size() * 4);
    std::vector<float>().swap(c->pending);
  }
  fs::remove(staged);
  // A chunk far over budget (a dense cell of the count grid) is split by streaming it into its
  // children, as often as needed.
  for (size_t i = 0; i < b.chunks.size(); ++i) {
    ChunkFile& c = *b.chunks[i];
    if (c.count <= b.chunk_cap * 3 / 2 || c.key.level >= kMaxLevel - 4) continue;
    std::vector<std::unique_ptr<ChunkFile>> kids(8);
    for (int k = 0; k < 8; ++k) {
      kids[size_t(k)] = std::make_unique<ChunkFile>();
      kids[size_t(k)]->key = c.key.child(k);
      kids[size_t(k)]->file = b.tmp / ("chunk-" + kids[size_t(k)]->key.name() + ".bin");
    }
    const glm::dvec3 centre = b.node_min(c.key) + glm::dvec3(b.node_size(c.key.level + 1));
    for_each_block(c.file, l, 65536, [&](const float* r, size_t count) {
      std::vector<float> out[8];
      for (size_t j = 0; j < count; ++j) {
        const float* rec = r + j * l.stride;
        const int o = int(double(rec[0]) >= centre.x) | int(double(rec[1]) >= centre.y) << 1 |
                      int(double(rec[2]) >= centre.z) << 2;
        out[o].insert(out[o].end(), rec, rec + l.stride);
      }
      for (int k = 0; k < 8; ++k) {
        if (out[k].empty()) continue;
        append_file(kids[size_t(k)]->file, out[k].data(), out[k].size() * 4);
        kids[size_t(k)]->count += out[k].size() / l.stride;
      }
    });
    fs::remove(c.file);
    b.chunks.erase(b.chunks.begin() + long(i));
    --i;
    for (auto& kid : kids)
      if (kid->count) b.chunks.push_back(std::move(kid));
  }
}

void build_chunks(SplatBuild& b) {
  b.pool->parallel_for(b.chunks.size(), 1, [&](size_t cb, size_t ce) {
    for (size_t ci = cb; ci < ce; ++ci) {
      ChunkFile& c = *b.chunks[ci];
      std::vector<float> recs = read_records(c.file);
      fs::remove(c.file);
      std::vector<float> scratch;
      io::SplatSet root = build_node(b, c.key, recs.data(), c.count, scratch);
      std::vector<float>().swap(recs);
      if (c.key.level == 0) continue;
      std::vector<float> out(root.size() * b.lay.stride);
      to_records(root, 0, root.size(), b.lay, out.data());
      const fs::path file = b.tmp / ("root-" + c.key.name() + ".bin");
      write_file(file, out.data(), out.size() * 4);
      std::lock_guard lock(b.mutex);
      b.pending[c.key] = file;
    }
  });
}

// From the deepest pending nodes up: each parent merges its children's representations.
void build_upper_levels(SplatBuild& b) {
  while (!b.pending.empty()) {
    int deepest = 0;
    for (auto& [k, f] : b.pending) deepest = std::max(deepest, k.level);
    std::map<Key, std::vector<Key>> parents;
    for (auto& [k, f] : b.pending)
      if (k.level == deepest) parents[k.parent()].push_back(k);
    std::vector<std::pair<Key, std::vector<Key>>> work(parents.begin(), parents.end());
    b.pool->parallel_for(work.size(), 1, [&](size_t wb, size_t we) {
      for (size_t w = wb; w < we; ++w) {
        const Key& p = work[w].first;
        io::SplatSet children;
        children.sh_degree = b.lay.degree;
        double child_error = 0;
        for (const Key& k : work[w].second) {
          fs::path file;
          {
            std::lock_guard lock(b.mutex);
            file = b.pending.at(k);
          }
          const std::vector<float> recs = read_records(file);
          fs::remove(file);
          io::append_splats(children, from_records(recs.data(), recs.size() / b.lay.stride, b.lay));
          child_error = std::max(child_error, error_of(b, k));
        }
        io::SplatSet merged = merge_node(b, p, children, child_error);
        if (p.level == 0) continue;
        std::vector<float> out(merged.size() * b.lay.stride);
        to_records(merged, 0, merged.size(), b.lay, out.data());
        const fs::path file = b.tmp / ("root-" + p.name() + ".bin");
        write_file(file, out.data(), out.size() * 4);
        std::lock_guard lock(b.mutex);
        b.pending[p] = file;
      }
    });
    for (auto& [p, kids] : work)
      for (const Key& k : kids) b.pending.erase(k);
  }
}

void write_tileset(SplatBuild& b) {
  using nlohmann::json;
  std::map<Key, std::vector<Key>> children;
  for (auto& [k, info] : b.nodes)
    if (k.level > 0) children[k.parent()].push_back(k);
  // Boxes: Y-up bounds of the content and the children, as Z-up tile boxes (x, -z, y).
  std::function<json(const Key&, Box&)> tile = [&](const Key& k, Box& box) {
    const NodeOut& info = b.nodes.at(k);
    box = info.bounds;
    json kids = json::array();
    for (const Key& c : children[k]) {
      Box cb;
      kids.push_back(tile(c, cb));
      box.add(cb);
    }
    const glm::dvec3 c = (box.min + box.max) * 0.5, h = (box.max - box.min) * 0.5 + 1e-6;
    json t = {{"boundingVolume", {{"box", {c.x, -c.z, c.y, h.x, 0, 0, 0, h.z, 0, 0, 0, h.y}}}},
              {"geometricError", info.error},
              {"refine", "REPLACE"},
              {"content", {{"uri", "tiles/" + k.name() + ".glb"}}}};
    if (!kids.empty()) t["children"] = std::move(kids);
    return t;
  };
  Box root_box;
  json root = tile(Key{}, root_box);
  if (b.transform != glm::dmat4(1.0)) {
    // The set's frame -> glTF's Y-up, seen in the Z-up tile frame: Y T Y^-1, with
    // Y (x, y, z) = (x, -z, y).
    const glm::dmat4 y(1, 0, 0, 0, 0, 0, 1, 0, 0, -1, 0, 0, 0, 0, 0, 1);
    const glm::dmat4 m = y * b.transform * glm::inverse(y);
    json t = json::array();
    for (int c = 0; c < 4; ++c)
      for (int r = 0; r < 4; ++r) t.push_back(std::abs(m[c][r]) < 1e-15 ? 0.0 : m[c][r]);
    root["transform"] = t;
  }
  const std::vector<std::string> gltf_extensions =
      b.opt.compression == SplatCompression::Spz
          ? std::vector<std::string>{"KHR_gaussian_splatting",
                                     "KHR_gaussian_splatting_compression_spz_2"}
          : std::vector<std::string>{"KHR_gaussian_splatting"};
  json content_gltf = {{"extensionsUsed", gltf_extensions}};
  if (b.opt.compression == SplatCompression::Spz)
    content_gltf["extensionsRequired"] = gltf_extensions;
  json tileset = {{"asset", {{"version", "1.1"}, {"generator", "stipple tile"}}},
                  {"geometricError", std::max(b.cube_size, 2 * b.nodes.at(Key{}).error)},
                  {"root", root},
                  // CesiumJS reads the glTF extensions the contents need from 3DTILES_content_gltf.
                  {"extensionsUsed", {"3DTILES_content_gltf"}},
                  {"extensions", {{"3DTILES_content_gltf", content_gltf}}},
                  {"extras",
                   {{"stipple",
                     {{"splats", b.total},
                      {"mergedSplats", b.merged_splats.load()},
                      {"shDegree", b.lay.degree},
                      {"source", b.format},
                      {"cube", {b.cube_min.x, b.cube_min.y, b.cube_min.z, b.cube_size}}}}}}};
  const std::string text = tileset.dump(1);
  write_file(b.dir / "tileset.json", text.data(), text.size());
}

}  // namespace

SplatTileStats build_splat_tileset(const SplatTileOptions& options) {
  const auto start = std::chrono::steady_clock::now();
  if (options.inputs.empty()) fail("tile: no input");
  if (options.max_leaf_splats < 1) fail("tile: a leaf holds at least one splat");
  SplatBuild b(options);
  const fs::path out = begin_output(b);
  const unsigned threads =
      options.threads ? options.threads : std::max(1u, std::thread::hardware_concurrency());
  b.pool = std::make_unique<ThreadPool>(threads);
  const fs::path staged = b.tmp / "staged.bin";
  const Box box = stage_inputs(b, staged);
  const glm::dvec3 extent = box.max - box.min;
  b.cube_size = std::max({extent.x, extent.y, extent.z}) * (1 + 1e-6) + 1e-6;
  b.cube_min = (box.min + box.max) * 0.5 - glm::dvec3(b.cube_size * 0.5);
  // A chunk being built holds its records, a partition copy, and the children's splats of the
  // node being merged: about 3 records a splat, for every worker at once, within half the budget.
  const uint64_t record_bytes = b.lay.stride * 4;
  b.chunk_cap =
      options.chunk_splats
          ? options.chunk_splats
          : size_t(std::max<uint64_t>(options.max_memory / 2 / (3 * record_bytes * threads),
                                      2 * options.max_leaf_splats));
  STIPPLE_INFO("tile: {} splats of SH degree {}, cube {:.3f}, chunks of <= {} splats, {} threads",
               b.total, b.lay.degree, b.cube_size, b.chunk_cap, threads);
  make_chunks(b, staged);
  build_chunks(b);
  build_upper_levels(b);
  if (b.leaf_splats != b.total)
    fail("internal error: {} splats in the leaves, {} read", b.leaf_splats.load(), b.total);
  write_tileset(b);
  fs::remove_all(b.tmp);
  if (fs::exists(out)) {
    fs::path old = out;
    old += fmt::format(".old-{}", ::getpid());
    fs::rename(out, old);
    fs::rename(b.dir, out);
    fs::remove_all(old);
  } else {
    fs::rename(b.dir, out);
  }
  b.partial.committed = true;

  SplatTileStats s;
  s.splats = b.total;
  s.merged_splats = b.merged_splats;
  s.bytes = b.bytes;
  s.chunks = b.chunks.size();
  s.sh_degree = b.lay.degree;
  for (auto& [k, info] : b.nodes) {
    ++s.tiles;
    s.leaves += info.leaf;
    s.depth = std::max(s.depth, k.level);
  }
  s.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return s;
}

}  // namespace stipple::tiler
