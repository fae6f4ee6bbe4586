#include "stipple/tiles3d/streamer.hpp"

#include <algorithm>
#include <condition_variable>
#include <cstring>
#include <optional>

#include <fmt/format.h>

#include "stipple/core/error.hpp"
#include "stipple/core/log.hpp"
#include "stipple/io/content_summary.hpp"
#include "stipple/io/copc.hpp"
#include "stipple/io/ept.hpp"
#include "stipple/io/glb_points.hpp"
#include "stipple/io/potree.hpp"
#include "stipple/io/splat_readers.hpp"

namespace stipple::tiles3d {

namespace {

// Whether a glb's JSON chunk names KHR_gaussian_splatting (its splat content, not points).
bool is_splat_glb(const std::vector<uint8_t>& bytes) {
  if (bytes.size() < 20 || std::memcmp(bytes.data(), "glTF", 4) != 0) return false;
  uint32_t length = 0;
  std::memcpy(&length, bytes.data() + 12, 4);
  const size_t n = std::min<size_t>(length, bytes.size() - 20);
  const std::string_view json(reinterpret_cast<const char*>(bytes.data() + 20), n);
  return json.find("KHR_gaussian_splatting") != std::string_view::npos;
}

}  // namespace

io::PointContent decode_content(const std::vector<uint8_t>& bytes, const std::string& uri,
                                const io::DecodeLimits& limits, const io::FetchOptions& fetch) {
  if (bytes.size() >= 4 && std::memcmp(bytes.data(), "pnts", 4) == 0)
    return io::decode_pnts(bytes, uri, limits);
  if (is_splat_glb(bytes)) {
    io::SplatLimits splat_limits;
    splat_limits.max_splats = size_t(limits.max_points);
    io::PointContent c;
    auto splats = std::make_shared<io::SplatSet>(io::decode_splats_glb(bytes, uri, splat_limits));
    c.point_count = splats->size();
    c.format = "glb splats";
    c.splats = std::move(splats);
    return c;
  }
  if ((bytes.size() >= 4 && std::memcmp(bytes.data(), "glTF", 4) == 0) ||
      io::uri_path(uri).ends_with(".gltf"))
    return io::decode_glb_points(bytes, uri, limits, [&](const std::string& u) {
      return io::fetch(io::resolve_uri(uri, u), fetch);
    });
  std::string magic;
  for (size_t i = 0; i < 4 && i < bytes.size(); ++i)
    magic += std::isprint(bytes[i]) ? char(bytes[i]) : '?';
  // Valid 3D Tiles content that is not points: no points, and a warning (once per kind, handed
  // out by the streamer).
  if (magic == "b3dm" || magic == "i3dm" || magic == "cmpt" || magic == "vctr" || magic == "geom") {
    io::PointContent c;
    c.format = magic;
    c.not_drawn = io::describe_content_type(magic);
    return c;
  }
  fail("{}: content type '{}' is not supported (pnts and glb point tiles are)", uri, magic);
}

std::string_view tile_problem_kind(std::string_view message) {
  const size_t colon = message.find(": ");
  if (colon != std::string_view::npos &&
      message.substr(0, colon).find(' ') == std::string_view::npos)
    message.remove_prefix(colon + 2);
  return message;
}

struct TileStreamer::Job {
  uint32_t tile;
  std::atomic<bool> cancelled{false};
  std::vector<io::PointContent> result;
  PreparedTile prepared;
  std::optional<io::Expansion> expansion;  // a read of pending children, not content
  std::string error;
  std::vector<std::string> warnings;  // the contents' own, "uri: text", taken before prepare
  bool complete = false;  // every content fetched and decoded (even if cancelled meanwhile)
  std::vector<std::string> not_drawn;  // what its contents hold that is not drawn
  uint64_t points = 0;                 // decoded (counted before prepare may consume the contents)
};

struct TileStreamer::Shared {
  std::mutex mutex;
  std::condition_variable done_cv;
  std::deque<std::shared_ptr<Job>> done;
};

TileStreamer::TileStreamer(std::shared_ptr<io::Tileset> tileset, StreamerOptions options)
    : tileset_(std::move(tileset)),
      options_(std::move(options)),
      shared_(std::make_shared<Shared>()),
      pool_(std::make_unique<ThreadPool>(std::max(1u, options_.threads))) {
  fetcher_ = options_.fetcher;
  if (!fetcher_)
    fetcher_ = [fetch = options_.fetch](const std::string& uri) { return io::fetch(uri, fetch); };
  options_.tileset.fetch = options_.fetch;
  not_drawn_ = options_.not_drawn_warned;
  grow();
}

TileStreamer::~TileStreamer() {
  for (auto& j : jobs_)
    if (j) j->cancelled = true;
  for (auto& j : expanding_) j->cancelled = true;
  pool_.reset();  // joins the workers
}

// Per-tile vectors follow the tile array as pending children are attached.
void TileStreamer::grow() {
  size_t n = tileset_->tiles.size();
  states_.resize(n);
  contents_.resize(n);
  jobs_.resize(n);
  warned_.resize(n);
}

void TileStreamer::evict(uint32_t e) {
  contents_[e].clear();
  contents_[e].shrink_to_fit();
  release_prepared(e);
  stats_.resident_bytes -= states_[e].bytes;
  // The size stays known: what reloading it would cost, for the budget.
  states_[e] = TileState{LoadState::Unloaded, states_[e].bytes, 0, states_[e].points};
  ++stats_.evictions;
}

void TileStreamer::integrate() {
  std::deque<std::shared_ptr<Job>> done;
  {
    std::lock_guard lock(shared_->mutex);
    done.swap(shared_->done);
  }
  for (auto& job : done) {
    --in_flight_;
    uint32_t t = job->tile;
    if (job->expansion) {
      std::erase(expanding_, job);
      // A cancelled read (shutdown) is never attached: the tile stays pending.
      if (job->cancelled) continue;
      ++stats_.expansions;
      for (const auto& w : job->expansion->warnings) new_warnings_.push_back({t, w});
      auto errors = io::attach_children(*tileset_, std::move(*job->expansion), options_.tileset);
      grow();
      for (auto& [tile, message] : errors) {
        new_errors_.push_back({tile, message});
        all_errors_.push_back({tile, std::move(message)});
      }
      continue;
    }
    jobs_[t].reset();
    // Content that is not drawn: once per kind, as a warning of the first tile that has it.
    for (const auto& what : job->not_drawn)
      if (not_drawn_.insert(what).second)
        new_warnings_.push_back(
            {t, fmt::format("content is {}, which stipple does not draw (points only)", what)});
    // A tile's content warnings are reported once, whatever reloads follow an eviction.
    if (!job->warnings.empty() && !warned_[t]) {
      warned_[t] = true;
      for (auto& w : job->warnings) new_warnings_.push_back({t, std::move(w)});
    }
    // Resident size of the result (0 for a failed load: its result and preparation are cleared).
    uint64_t bytes = job->prepared.bytes;
    for (const auto& c : job->result) bytes += c.memory_bytes();
    if (job->cancelled) {
      states_[t].state = LoadState::Unloaded;
      if (job->complete) {  // known now, for the budgets
        states_[t].bytes = bytes;
        states_[t].points = job->points;
      }
      // Cancelled after the work was done: kept where it fits without evicting anything.
      if (!job->complete || stats_.resident_bytes + bytes > options_.traversal.memory_budget) {
        ++stats_.loads_cancelled;
        continue;
      }
      make_resident(*job, bytes);
      continue;
    }
    if (!job->error.empty()) {
      states_[t].state = LoadState::Failed;
      // Reported by whoever takes the errors (take_errors), once.
      new_errors_.push_back({t, job->error});
      all_errors_.push_back({t, job->error});
      continue;
    }
    // Results arrive before this frame's selection: the previous frame's tiles (being drawn,
    // and within the budget with this one) are not evicted for it.
    bool fits = false;
    auto evict_list =
        make_room(states_, bytes, options_.traversal.memory_budget, frame_ - 1, &fits);
    if (!fits) {
      // Larger than the selection assumed, and not even evicting every unused tile makes room:
      // dropped, but its size is now known, so the traversal plans with it from now on.
      states_[t].state = LoadState::Unloaded;
      states_[t].bytes = bytes;
      states_[t].points = job->points;
      ++stats_.discarded_over_budget;
      continue;
    }
    for (uint32_t e : evict_list) evict(e);
    make_resident(*job, bytes);
  }
}

// last_used stays the frame that last asked for the tile: one nobody wants any more (a REPLACE
// parent whose children arrived first) is not made to look fresh.
void TileStreamer::make_resident(Job& job, uint64_t bytes) {
  const uint32_t t = job.tile;
  contents_[t] = std::move(job.result);
  if (job.prepared.chunks) {
    if (t >= prepared_.size()) prepared_.resize(size_t(t) + 1);
    prepared_[t] = std::move(job.prepared);
  }
  states_[t].state = LoadState::Loaded;
  states_[t].bytes = bytes;
  states_[t].points = job.points;
  stats_.resident_bytes += bytes;
  stats_.peak_resident_bytes = std::max(stats_.peak_resident_bytes, stats_.resident_bytes);
  ++stats_.loads_completed;
}

const Selection& TileStreamer::update(const View& view) {
  ++frame_;
  integrate();
  selection_ = select_tiles(*tileset_, view, states_, options_.traversal, frame_);
  for (uint32_t t : selection_.used) states_[t].last_used = frame_;
  for (uint32_t e : selection_.evict) evict(e);
  for (uint32_t c : selection_.cancel)
    if (jobs_[c]) jobs_[c]->cancelled = true;  // its worker skips the work or its result
  // The queues are this frame's wish list: what is no longer asked for is dropped (cancelled).
  queue_.clear();
  for (const auto& r : selection_.loads)
    if (states_[r.tile].state == LoadState::Unloaded) queue_.push_back(r);
  expand_queue_.clear();
  for (const auto& r : selection_.expands)
    if (tileset_->tiles[r.tile].pending &&
        std::none_of(expanding_.begin(), expanding_.end(),
                     [&](const auto& j) { return j->tile == r.tile; }))
      expand_queue_.push_back(r);
  start_jobs();
  return selection_;
}

void TileStreamer::start_jobs() {
  // Pending children first: small reads that gate everything below them.
  size_t next = 0;
  while (in_flight_ < options_.max_in_flight && next < expand_queue_.size()) {
    uint32_t t = expand_queue_[next++].tile;
    auto job = std::make_shared<Job>();
    job->tile = t;
    job->expansion.emplace();
    expanding_.push_back(job);
    ++in_flight_;
    // The worker gets its own references: the tile array may move while it reads.
    pool_->submit([job, pending = tileset_->tiles[t].pending, tiles_now = tileset_->tiles.size(),
                   shared = shared_, fetcher = fetcher_, options = options_.tileset] {
      if (!job->cancelled)
        *job->expansion = io::read_children(job->tile, *pending, tiles_now, fetcher, options);
      std::lock_guard lock(shared->mutex);
      shared->done.push_back(job);
      shared->done_cv.notify_all();
    });
  }
  expand_queue_.erase(expand_queue_.begin(), expand_queue_.begin() + std::ptrdiff_t(next));
  next = 0;
  while (in_flight_ < options_.max_in_flight && next < queue_.size()) {
    uint32_t t = queue_[next++].tile;
    auto job = std::make_shared<Job>();
    job->tile = t;
    jobs_[t] = job;
    states_[t].state = LoadState::Loading;
    ++in_flight_;
    std::vector<std::string> uris = tileset_->tiles[t].contents;
    pool_->submit([job, uris, transform = tileset_->tiles[t].transform, shared = shared_,
                   fetcher = fetcher_, fetch = options_.fetch, limits = options_.limits,
                   prepare = options_.prepare, copc = tileset_->copc, potree = tileset_->potree,
                   ept = tileset_->ept] {
      try {
        for (const auto& uri : uris) {
          if (job->cancelled) break;
          auto bytes = fetcher(uri);
          // Decoded even when cancelled meanwhile: far cheaper than fetching it again, and the
          // result is kept where it fits.
          job->result.push_back(copc     ? io::decode_copc_node(*copc, bytes, uri, limits)
                                : potree ? io::decode_potree_node(*potree, bytes, uri, limits)
                                : ept    ? io::decode_ept_node(*ept, bytes, uri, limits)
                                         : decode_content(bytes, uri, limits, fetch));
        }
        job->complete = job->result.size() == uris.size();
        for (size_t i = 0; i < job->result.size(); ++i) {
          job->points += job->result[i].point_count;
          if (!job->result[i].not_drawn.empty()) job->not_drawn.push_back(job->result[i].not_drawn);
          for (const auto& w : job->result[i].warnings)
            job->warnings.push_back(fmt::format("{}: {}", uris[i], w));
        }
        // Prepared even when cancelled meanwhile, like the decode: the result may be kept.
        if (prepare && job->complete) job->prepared = prepare(job->tile, transform, job->result);
      } catch (const std::exception& e) {
        job->error = e.what();
        job->result.clear();
        job->prepared = {};
        job->complete = false;
      }
      std::lock_guard lock(shared->mutex);
      shared->done.push_back(job);
      shared->done_cv.notify_all();
    });
  }
  queue_.erase(queue_.begin(), queue_.begin() + std::ptrdiff_t(next));
}

void TileStreamer::wait_for_progress() {
  if (in_flight_ == 0) return;
  std::unique_lock lock(shared_->mutex);
  shared_->done_cv.wait(lock, [&] { return !shared_->done.empty(); });
}

bool TileStreamer::has_results() const {
  std::lock_guard lock(shared_->mutex);
  return !shared_->done.empty();
}

bool TileStreamer::idle() const {
  return in_flight_ == 0 && queue_.empty() && expand_queue_.empty();
}

const std::vector<io::PointContent>* TileStreamer::content(uint32_t tile) const {
  if (tile >= states_.size() || states_[tile].state != LoadState::Loaded) return nullptr;
  return &contents_[tile];
}

const PreparedTile* TileStreamer::prepared(uint32_t tile) const {
  if (tile >= states_.size() || states_[tile].state != LoadState::Loaded) return nullptr;
  if (tile >= prepared_.size() || !prepared_[tile].chunks) return nullptr;
  return &prepared_[tile];
}

void TileStreamer::release_prepared(uint32_t tile) {
  if (tile < prepared_.size()) prepared_[tile] = {};
}

std::vector<TileError> TileStreamer::take_errors() {
  std::vector<TileError> out;
  out.swap(new_errors_);
  return out;
}

std::vector<TileError> TileStreamer::take_warnings() {
  std::vector<TileError> out;
  out.swap(new_warnings_);
  return out;
}

StreamerStats TileStreamer::stats() const {
  StreamerStats s = stats_;
  s.in_flight = in_flight_;
  s.queued = uint32_t(queue_.size() + expand_queue_.size());
  s.expanding = uint32_t(expanding_.size());
  s.budget_limited = selection_.budget_limited;
  s.sse_threshold = selection_.sse_threshold;
  for (const auto& st : states_) {
    s.loaded += st.state == LoadState::Loaded;
    s.failed += st.state == LoadState::Failed;
  }
  return s;
}

}  // namespace stipple::tiles3d
