#include "stipple/io/copc.hpp"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <map>
#include <tuple>

#include <fmt/format.h>

#include "las_detail.hpp"
#include "stipple/core/error.hpp"
#include "stipple/core/log.hpp"

namespace stipple::io {
namespace {

constexpr size_t kHeader14 = 375;  // LAS 1.4 header size: COPC files have exactly this
constexpr size_t kVlrHeader = 54;
constexpr size_t kInfoSize = 160;
constexpr size_t kEntrySize = 32;
// Problems listed one by one for a page; past this they are counted. A damaged page can have
// thousands (every entry), and formatting each message was most of the time spent on it.
constexpr size_t kMaxPageErrors = 32;
constexpr uint64_t kMaxPrefixBytes = 64ull << 20;  // header and VLRs read at open

using detail::load;
using detail::store;

bool ends_with_ci(const std::string& s, std::string_view suffix) {
  if (s.size() < suffix.size()) return false;
  for (size_t i = 0; i < suffix.size(); ++i)
    if (std::tolower(static_cast<unsigned char>(s[s.size() - suffix.size() + i])) != suffix[i])
      return false;
  return true;
}

// Offset of the LASzip VLR's chunk size field in the prefix; 0 when there is none.
size_t laszip_chunk_field(std::span<const uint8_t> prefix, uint32_t vlr_count) {
  size_t at = kHeader14;
  for (uint32_t i = 0; i < vlr_count && at + kVlrHeader <= prefix.size(); ++i) {
    std::string user(reinterpret_cast<const char*>(prefix.data() + at + 2),
                     strnlen(reinterpret_cast<const char*>(prefix.data() + at + 2), 16));
    const uint16_t record = load<uint16_t>(prefix.data() + at + 18);
    const uint16_t length = load<uint16_t>(prefix.data() + at + 20);
    if (user == "laszip encoded" && record == 22204 && length >= 16 &&
        at + kVlrHeader + 16 <= prefix.size())
      return at + kVlrHeader + 12;
    at += kVlrHeader + length;
  }
  return 0;
}

struct NodeRef {
  uint64_t points = 0;
};

uint64_t node_points(const std::string& uri) {
  const std::string value = fragment_field(uri, "points");
  unsigned long long n = 0;
  char tail = 0;
  if (value.empty() || std::sscanf(value.c_str(), "%llu%c", &n, &tail) != 1)
    fail("{}: not a COPC node (no point count in the URI)", uri);
  return n;
}

// One node's chunk as a LAZ file of its own: the file's header and VLRs with the node's point
// count, the LASzip chunk size set to it (one fixed-size chunk), no EVLRs, and a chunk table
// pointer at itself (LASzip's "no table", valid for fixed-size chunks).
std::vector<uint8_t> node_as_laz(const CopcFile& file, uint64_t points,
                                 std::span<const uint8_t> chunk) {
  std::vector<uint8_t> out(file.prefix.size() + 8 + chunk.size());
  std::memcpy(out.data(), file.prefix.data(), file.prefix.size());
  uint8_t* h = out.data();
  store<uint32_t>(h + 107, 0);  // legacy counts: 0 for formats 6-10
  for (int i = 0; i < 5; ++i) store<uint32_t>(h + 111 + 4 * i, 0);
  store<uint64_t>(h + 227, 0);  // no waveform data
  store<uint64_t>(h + 235, 0);  // no EVLRs
  store<uint32_t>(h + 243, 0);
  store<uint64_t>(h + 247, points);
  for (int i = 0; i < 15; ++i) store<uint64_t>(h + 255 + 8 * i, 0);
  const size_t field = laszip_chunk_field(file.prefix, load<uint32_t>(h + 100));
  if (field == 0) fail("{}: no LASzip VLR", file.uri);
  store<uint32_t>(h + field, uint32_t(std::max<uint64_t>(points, 1)));
  store<int64_t>(h + file.prefix.size(), int64_t(file.prefix.size()));
  if (!chunk.empty()) std::memcpy(h + file.prefix.size() + 8, chunk.data(), chunk.size());
  return out;
}

PointBatch decode_node_batch(const CopcFile& file, std::span<const uint8_t> chunk, uint64_t points,
                             const std::string& uri, int* rgb_bits) {
  std::vector<uint8_t> laz = node_as_laz(file, points, chunk);
  LasReader reader(laz, uri);
  if (rgb_bits) *rgb_bits = reader.header().rgb_bits;
  PointBatch batch;
  batch.reserve(points);
  while (batch.size() < points)
    if (reader.read(batch, size_t(points - batch.size())) == 0) break;
  if (batch.size() != points)
    fail("{}: the node's chunk decoded {} points, the hierarchy says {}", uri, batch.size(),
         points);
  return batch;
}

std::string node_uri(const CopcFile& file, const CopcEntry& e) {
  return fmt::format("{}&points={}&key={}", range_uri(file.uri, e.offset, uint64_t(e.byte_size)),
                     e.point_count, e.key.str());
}

BoundingVolume node_volume(const CopcInfo& info, const CopcKey& key) {
  double half = 0;
  glm::dvec3 c = copc_node_center(info, key, &half);
  BoundingVolume v;
  v.kind = BoundingVolume::Kind::Box;
  v.box = {c.x, c.y, c.z, half, 0, 0, 0, half, 0, 0, 0, half};
  return v;
}

Tile node_tile(const CopcFile& file, const CopcKey& key) {
  Tile t;
  t.volume = node_volume(file.info, key);
  t.box = obb_of(t.volume, t.transform);
  t.geometric_error = file.info.spacing / std::ldexp(1.0, key.d);
  t.refine = Refine::Add;
  return t;
}

std::shared_ptr<PendingChildren> page_pending(std::shared_ptr<const CopcFile> file,
                                              const CopcKey& key, uint64_t offset, uint64_t size) {
  auto p = std::make_shared<PendingChildren>();
  p->kind = PendingChildren::Kind::CopcPage;
  p->uris = {range_uri(file->uri, offset, size)};
  p->refine = Refine::Add;
  p->level = uint32_t(key.d);
  p->x = uint32_t(key.x);
  p->y = uint32_t(key.y);
  p->z = uint32_t(key.z);
  p->copc = std::move(file);
  return p;
}

}  // namespace

std::string CopcKey::str() const {
  return fmt::format("{}-{}-{}-{}", d, x, y, z);
}

glm::dvec3 copc_node_center(const CopcInfo& info, const CopcKey& key, double* halfsize) {
  const double side = 2.0 * info.halfsize / std::ldexp(1.0, key.d);
  const glm::dvec3 min = info.center - glm::dvec3(info.halfsize);
  if (halfsize) *halfsize = side * 0.5;
  return min + side * (glm::dvec3(key.x, key.y, key.z) + 0.5);
}

CopcInfo parse_copc_info(std::span<const uint8_t> p, const std::string& name) {
  if (p.size() < kInfoSize)
    fail("{}: the COPC info VLR has {} bytes, not {}", name, p.size(), kInfoSize);
  CopcInfo info;
  info.center = {load<double>(&p[0]), load<double>(&p[8]), load<double>(&p[16])};
  info.halfsize = load<double>(&p[24]);
  info.spacing = load<double>(&p[32]);
  info.root_hier_offset = load<uint64_t>(&p[40]);
  info.root_hier_size = load<uint64_t>(&p[48]);
  info.gpstime_min = load<double>(&p[56]);
  info.gpstime_max = load<double>(&p[64]);
  for (int i = 0; i < 3; ++i)
    if (!std::isfinite(info.center[i])) fail("{}: COPC info: the root centre is not finite", name);
  if (!(std::isfinite(info.halfsize) && info.halfsize > 0))
    fail("{}: COPC info: root half size {} is not a positive number", name, info.halfsize);
  if (!(std::isfinite(info.spacing) && info.spacing > 0))
    fail("{}: COPC info: root spacing {} is not a positive number", name, info.spacing);
  if (info.root_hier_size == 0 || info.root_hier_size % kEntrySize != 0)
    fail("{}: COPC info: root hierarchy page size {} is not a positive multiple of 32", name,
         info.root_hier_size);
  return info;
}

namespace {

// A message for entry_problem, formatted only when it is to be said.
template <typename... Args>
std::string said(bool say, fmt::format_string<Args...> format, Args&&... args) {
  return say ? fmt::format(format, std::forward<Args>(args)...) : std::string("-");
}

// Why an entry cannot be used, or nothing. Returned, not thrown: a damaged page has an error per
// entry (thousands), and unwinding a throw for each took most of the time of reading one.
// With `say` false the answer is only empty or not (no message is formatted).
std::string entry_problem(const CopcEntry& e, size_t i, const std::string& name, uint64_t file_size,
                          bool say = true) {
  const CopcKey& k = e.key;
  if (k.d < 0 || k.d > kMaxCopcDepth)
    return said(say, "{}: hierarchy entry {}: depth {} is outside 0-{}", name, i, k.d,
                kMaxCopcDepth);
  const int64_t cells = int64_t(1) << k.d;
  if (k.x < 0 || k.y < 0 || k.z < 0 || k.x >= cells || k.y >= cells || k.z >= cells)
    return said(say, "{}: hierarchy entry {}: key {} is outside its level's {} cells per axis",
                name, i, k.str(), cells);
  if (e.point_count < -1)
    return said(say, "{}: node {}: point count {} is negative", name, k.str(), e.point_count);
  if (e.byte_size < 0)
    return said(say, "{}: node {}: byte size {} is negative", name, k.str(), e.byte_size);
  if (e.point_count == -1 && (e.byte_size == 0 || e.byte_size % int32_t(kEntrySize) != 0))
    return said(say,
                "{}: node {}: child hierarchy page of {} bytes is not a positive multiple of 32",
                name, k.str(), e.byte_size);
  if (e.point_count > 0 && e.byte_size == 0)
    return said(say, "{}: node {}: {} points in a chunk of 0 bytes", name, k.str(), e.point_count);
  if (e.byte_size > 0) {
    if (e.offset < kHeader14 || e.offset > UINT64_MAX - uint64_t(e.byte_size))
      return said(say, "{}: node {}: offset {} is inside the header", name, k.str(), e.offset);
    if (file_size > 0 && e.offset + uint64_t(e.byte_size) > file_size)
      return said(say, "{}: node {}: bytes {}-{} are past the end of the file ({} bytes)", name,
                  k.str(), e.offset, e.offset + uint64_t(e.byte_size) - 1, file_size);
  }
  return {};
}

}  // namespace

std::vector<CopcEntry> parse_copc_page(std::span<const uint8_t> bytes, const std::string& name,
                                       uint64_t file_size, std::vector<std::string>* errors) {
  if (bytes.size() % kEntrySize != 0)
    fail("{}: hierarchy page of {} bytes is not a whole number of 32-byte entries", name,
         bytes.size());
  std::vector<CopcEntry> out;
  out.reserve(bytes.size() / kEntrySize);
  const size_t errors_before = errors ? errors->size() : 0;
  size_t unsaid = 0;
  for (size_t i = 0; i < bytes.size() / kEntrySize; ++i) {
    const uint8_t* p = bytes.data() + i * kEntrySize;
    CopcEntry e;
    e.key = {load<int32_t>(p), load<int32_t>(p + 4), load<int32_t>(p + 8), load<int32_t>(p + 12)};
    e.offset = load<uint64_t>(p + 16);
    e.byte_size = load<int32_t>(p + 24);
    e.point_count = load<int32_t>(p + 28);
    const bool say = !errors || errors->size() - errors_before < kMaxPageErrors;
    if (std::string problem = entry_problem(e, i, name, file_size, say); !problem.empty()) {
      if (!errors) fail("{}", problem);
      if (say)
        errors->push_back(std::move(problem));
      else
        ++unsaid;
      continue;
    }
    out.push_back(e);
  }
  if (unsaid)
    errors->push_back(fmt::format("{}: {} more entries cannot be used (not listed)", name, unsaid));
  return out;
}

bool is_copc_input(const std::string& uri) {
  if (ends_with_ci(uri_path(uri), ".copc.laz")) return true;
  if (is_url(uri) || !(ends_with_ci(uri, ".laz") || ends_with_ci(uri, ".las"))) return false;
  // A COPC file's first VLR is its info: user id "copc" right after the 1.4 header.
  std::ifstream in(uri, std::ios::binary);
  char head[kHeader14 + 8] = {};
  if (!in.read(head, sizeof(head))) return false;
  return std::memcmp(head, "LASF", 4) == 0 && std::memcmp(head + kHeader14 + 2, "copc", 4) == 0;
}

std::shared_ptr<const CopcFile> open_copc(const std::string& uri, const Fetcher& fetcher,
                                          const DecodeLimits&) {
  auto file = std::make_shared<CopcFile>();
  file->uri = uri;
  if (!is_url(uri)) {
    std::error_code ec;
    file->file_size = std::filesystem::file_size(uri, ec);
    if (ec) fail("{}: cannot open ({})", uri, ec.message());
  }
  const std::vector<uint8_t> head = fetcher(range_uri(uri, 0, kHeader14 + kVlrHeader + kInfoSize));
  if (head.size() < kHeader14 + kVlrHeader + kInfoSize || std::memcmp(head.data(), "LASF", 4) != 0)
    fail("{}: not a LAS file (no LASF signature)", uri);
  const uint8_t major = head[24], minor = head[25];
  const uint16_t header_size = load<uint16_t>(&head[94]);
  const uint32_t offset_to_points = load<uint32_t>(&head[96]);
  if (major != 1 || minor != 4 || header_size != kHeader14)
    fail("{}: COPC needs LAS 1.4 with a 375-byte header (this is LAS {}.{}, {} bytes)", uri, major,
         minor, header_size);
  if (std::memcmp(&head[kHeader14 + 2], "copc", 4) != 0 ||
      load<uint16_t>(&head[kHeader14 + 18]) != 1)
    fail("{}: not COPC: the first VLR is not the COPC info (user id \"copc\", record 1)", uri);
  if (offset_to_points < kHeader14 + kVlrHeader + kInfoSize || offset_to_points > kMaxPrefixBytes)
    fail("{}: offset to point data {} is not plausible for COPC", uri, offset_to_points);
  file->info = parse_copc_info(std::span(head).subspan(kHeader14 + kVlrHeader, kInfoSize), uri);
  file->prefix = fetcher(range_uri(uri, 0, offset_to_points));
  if (file->prefix.size() != offset_to_points) fail("{}: short read of the header and VLRs", uri);
  // The header as every other reader sees it: parsed from a node-less copy of the file.
  std::vector<uint8_t> empty = node_as_laz(*file, 0, {});
  store<uint64_t>(empty.data() + 247, 0);
  LasReader reader(empty, uri);
  // Local files: the header as read_las_header gives it (EVLRs listed too).
  file->header = is_url(uri) ? reader.header() : read_las_header(uri);
  if (is_url(uri)) file->header.rgb_bits = 16;
  file->header.path = uri;
  file->header.copc = true;
  file->header.point_count = load<uint64_t>(&file->prefix[247]);
  for (int i = 0; i < 15; ++i)
    file->header.points_by_return[i] = load<uint64_t>(&file->prefix[255 + 8 * i]);
  if (file->header.point_format < 6 || file->header.point_format > 8)
    fail("{}: COPC allows point formats 6-8, not {}", uri, file->header.point_format);
  const CopcInfo& info = file->info;
  if (file->file_size > 0 && (info.root_hier_offset > file->file_size ||
                              info.root_hier_size > file->file_size - info.root_hier_offset))
    fail("{}: COPC info: the root hierarchy page ({} bytes at {}) is past the end of the file", uri,
         info.root_hier_size, info.root_hier_offset);
  return file;
}

Expansion read_copc_page(uint32_t tile, const PendingChildren& pending, size_t tiles_now,
                         const Fetcher& fetcher, const TilesetOptions& options) {
  Expansion e;
  e.tile = tile;
  const CopcKey root{int32_t(pending.level), int32_t(pending.x), int32_t(pending.y),
                     int32_t(pending.z)};
  const std::string name = fmt::format("{} (hierarchy page of node {})",
                                       pending.copc ? pending.copc->uri : "?", root.str());
  try {
    if (!pending.copc || pending.uris.size() != 1) fail("a hierarchy page without its file");
    const CopcFile& file = *pending.copc;
    const std::vector<uint8_t> bytes = fetcher(pending.uris[0]);
    std::vector<std::string> bad;
    std::vector<CopcEntry> entries = parse_copc_page(bytes, name, file.file_size, &bad);
    for (auto& message : bad) e.errors.emplace_back(-1, std::move(message));
    // Problems of the entries' tree, listed up to kMaxPageErrors, then counted.
    size_t unsaid = 0;
    auto problem = [&]<typename... Args>(fmt::format_string<Args...> format, Args&&... args) {
      if (e.errors.size() < kMaxPageErrors)
        e.errors.emplace_back(-1, fmt::format(format, std::forward<Args>(args)...));
      else
        ++unsaid;
    };
    std::sort(entries.begin(), entries.end(), [](const CopcEntry& a, const CopcEntry& b) {
      return std::tie(a.key.d, a.key.x, a.key.y, a.key.z) <
             std::tie(b.key.d, b.key.x, b.key.y, b.key.z);
    });
    std::map<std::tuple<int32_t, int32_t, int32_t, int32_t>, int32_t> index;
    bool own = false;
    for (size_t i = 0; i < entries.size(); ++i) {
      const CopcEntry& en = entries[i];
      const CopcKey& k = en.key;
      if (i > 0 && entries[i - 1].key == k) {
        problem("{}: node {} is listed twice", name, k.str());
        continue;
      }
      if (k == root) {
        if (en.point_count == -1) {
          problem("{}: node {} points to a page of its own (a cycle)", name, k.str());
        } else if (en.point_count > 0) {
          e.contents.push_back(node_uri(file, en));
          e.content_points = uint64_t(en.point_count);
        }
        own = true;
        continue;
      }
      const int shift = k.d - root.d;
      if (shift <= 0 || (k.x >> shift) != root.x || (k.y >> shift) != root.y ||
          (k.z >> shift) != root.z) {
        problem("{}: node {} is not below the page's node", name, k.str());
        continue;
      }
      int32_t parent = -1;
      if (shift > 1) {
        auto it = index.find({k.d - 1, k.x >> 1, k.y >> 1, k.z >> 1});
        if (it == index.end()) {
          problem("{}: node {} has no parent in the hierarchy", name, k.str());
          continue;
        }
        parent = it->second;
      }
      if (tiles_now + e.tiles.size() + 1 > options.max_tiles) {
        e.over_limit = true;
        fail("the tile limit of {} is reached (TilesetOptions::max_tiles)", options.max_tiles);
      }
      Tile t = node_tile(file, k);
      t.parent = parent;
      t.depth = uint32_t(shift - 1);
      if (en.point_count > 0) {
        t.contents.push_back(node_uri(file, en));
        t.content_points = uint64_t(en.point_count);
      }
      if (en.point_count == -1)
        t.pending = page_pending(pending.copc, k, en.offset, uint64_t(en.byte_size));
      const int32_t local = int32_t(e.tiles.size());
      if (parent >= 0) e.tiles[size_t(parent)].children.push_back(uint32_t(local));
      index[{k.d, k.x, k.y, k.z}] = local;
      e.tiles.push_back(std::move(t));
    }
    if (unsaid)
      e.errors.emplace_back(
          -1, fmt::format("{}: {} more problems with its entries (not listed)", name, unsaid));
    e.subtrees = 1;
    if (!own)
      e.errors.emplace_back(
          -1, fmt::format("{}: the page does not list its own node {}", name, root.str()));
  } catch (const std::exception& err) {
    e.tiles.clear();
    e.contents.clear();
    e.errors.emplace_back(-1, err.what());
  }
  return e;
}

Tileset load_copc_tileset(const std::string& uri, const Fetcher& fetcher,
                          const TilesetOptions& options) {
  auto opened = open_copc(uri, fetcher);
  auto file = std::make_shared<CopcFile>(*opened);
  Tileset ts;
  ts.uri = uri;
  ts.version = "COPC 1.0";
  ts.geometric_error = 2.0 * file->info.spacing;
  Tile root = node_tile(*file, {});
  ts.tiles.push_back(std::move(root));
  auto pending = page_pending(file, {}, file->info.root_hier_offset, file->info.root_hier_size);
  // The root page is read now: a file whose hierarchy cannot even start is an error.
  Expansion e = read_copc_page(0, *pending, 1, fetcher, options);
  if (e.tiles.empty() && e.contents.empty())
    fail("{}", e.errors.empty() ? uri + ": the root hierarchy page is empty" : e.errors[0].second);
  // Colour depth from the root node (a sample of the whole cloud), as LasReader decides it
  // from a file's first chunk: one answer for every node.
  if (file->header.has_rgb && !e.contents.empty()) {
    ByteRange r;
    if (parse_range_uri(e.contents[0], &r)) {
      auto chunk = fetcher(e.contents[0]);
      int bits = 16;
      (void)decode_node_batch(*file, chunk, node_points(e.contents[0]), e.contents[0], &bits);
      file->rgb_bits = bits;
    }
  }
  ts.tiles[0].pending = pending;
  ts.pending = 1;
  ts.copc = file;
  // Every pending page names the final file (rgb_bits decided).
  pending->copc = file;
  for (auto& t : e.tiles)
    if (t.pending) std::const_pointer_cast<PendingChildren>(t.pending)->copc = file;
  // Its errors are the tileset's (ts.errors), for the reader to report.
  attach_children(ts, std::move(e), options);
  return ts;
}

Tileset load_copc_tileset(const std::string& uri, const TilesetOptions& options) {
  Fetcher fetcher = [&options](const std::string& u) { return fetch(u, options.fetch); };
  return load_copc_tileset(uri, fetcher, options);
}

PointContent decode_copc_node(const CopcFile& file, std::span<const uint8_t> chunk,
                              const std::string& uri, const DecodeLimits& limits) {
  const uint64_t points = node_points(uri);
  if (points > limits.max_points)
    fail("{}: {} points in one node is over the limit of {}", uri, points, limits.max_points);
  PointBatch b = decode_node_batch(file, chunk, points, uri, nullptr);
  PointContent c;
  c.format = "copc";
  c.point_count = b.size();
  glm::dvec3 lo(INFINITY), hi(-INFINITY);
  for (const auto& p : b.positions) {
    lo = glm::min(lo, p);
    hi = glm::max(hi, p);
  }
  c.center = b.size() ? (lo + hi) * 0.5 : glm::dvec3(0.0);
  c.positions.reserve(b.size());
  for (const auto& p : b.positions) c.positions.push_back(glm::vec3(p - c.center));
  if (!b.rgb.empty()) {
    c.rgba.reserve(b.size());
    const int shift = file.rgb_bits == 8 ? 0 : 8;
    for (const auto& v : b.rgb) {
      auto ch = [&](uint16_t x) { return uint32_t(std::min<uint32_t>(x >> shift, 255u)); };
      c.rgba.push_back(ch(v.x) | ch(v.y) << 8 | ch(v.z) << 16 | 0xff000000u);
    }
  }
  auto scalar = [&](const char* key, const char* type, auto const& values) {
    if (values.empty()) return;
    PointAttribute a;
    a.component_type = type;
    a.values.assign(values.begin(), values.end());
    c.attributes.emplace(key, std::move(a));
  };
  scalar("intensity", "UNSIGNED_SHORT", b.intensity);
  scalar("classification", "UNSIGNED_BYTE", b.classification);
  scalar("return_number", "UNSIGNED_BYTE", b.return_number);
  scalar("number_of_returns", "UNSIGNED_BYTE", b.number_of_returns);
  return c;
}

}  // namespace stipple::io
