#pragma once
// Streams tile content for a view: runs select_tiles every update, fetches and decodes requested
// tiles on a worker pool (off the calling thread), cancels what is no longer wanted, and keeps
// resident content within a memory budget by evicting least recently used tiles.
//
// The tile tree grows while streaming: external tilesets and child subtrees the traversal asks
// for are read on the worker pool too (io::read_children) and attached in update(), on the
// calling thread. Tile indices never change, but the tileset's tile array may reallocate in
// update(): read the tileset on that thread only, and hand workers copies of what they need.
#include <atomic>
#include <deque>
#include <functional>
#include <memory>
#include <mutex>
#include <set>
#include <string>
#include <string_view>
#include <vector>

#include "stipple/core/thread_pool.hpp"
#include "stipple/io/fetch.hpp"
#include "stipple/io/pnts.hpp"
#include "stipple/io/tileset.hpp"
#include "stipple/tiles3d/tile_chunks.hpp"
#include "stipple/tiles3d/traversal.hpp"

namespace stipple::tiles3d {

// What StreamerOptions::prepare made of a tile: its render-ready chunks and their size, which
// counts towards the memory budget like decoded content.
struct PreparedTile {
  std::shared_ptr<const TileChunks> chunks;
  uint64_t bytes = 0;
};
// Runs on a worker right after a tile's contents are decoded (conversion to render-ready data),
// so the thread calling update() never does it. It may consume `contents` (move from or clear
// them: what it leaves stays resident and counted). `transform` is the tile's, copied when the
// load started (the tile array may grow meanwhile). Throwing fails the tile like a decode error.
using PrepareTile = std::function<PreparedTile(uint32_t tile, const glm::dmat4& transform,
                                               std::vector<io::PointContent>& contents)>;

struct StreamerOptions {
  TraversalOptions traversal;
  io::FetchOptions fetch;
  io::DecodeLimits limits;
  unsigned threads = 4;        // worker threads (I/O bound: more than cores is fine)
  unsigned max_in_flight = 8;  // tiles fetched or decoded, tilesets or subtrees read, at once
  PrepareTile prepare;         // optional post-decode step on the worker
  io::TilesetOptions tileset;  // limits for reading pending children (its fetch is unused)
  // Fetches content, external tilesets and subtrees, from any worker thread (tests count or
  // fault requests with it); null: io::fetch with `fetch`.
  io::Fetcher fetcher;
  // Kinds of content not drawn that were warned about already (drawable_world_bounds): the
  // streamer warns once for each other kind it meets.
  std::set<std::string> not_drawn_warned;
};

struct TileError {
  uint32_t tile;
  std::string message;
};

// A tile problem's text without the content URI it starts with ("tiles/r12.pnts: ..."): what
// tells one kind of problem from another, so that each kind is reported once per tileset.
std::string_view tile_problem_kind(std::string_view message);

struct StreamerStats {
  uint64_t resident_bytes = 0;
  uint64_t peak_resident_bytes = 0;
  uint32_t loaded = 0, failed = 0, in_flight = 0, queued = 0;
  uint64_t loads_completed = 0, loads_cancelled = 0, evictions = 0, discarded_over_budget = 0;
  uint64_t expansions = 0;  // tiles whose pending children (tilesets, subtrees) were read
  uint32_t expanding = 0;   // of those in flight
  // The latest selection: whether the budget limited detail, and the threshold it used.
  bool budget_limited = false;
  double sse_threshold = 0;
};

// Decodes one content by its URI's extension or magic (pnts, glb, glTF). Throws stipple::Error.
io::PointContent decode_content(const std::vector<uint8_t>& bytes, const std::string& uri,
                                const io::DecodeLimits& limits, const io::FetchOptions& fetch);

class TileStreamer {
 public:
  // The streamer grows `tileset` as it reads pending children (others may read it, see above).
  TileStreamer(std::shared_ptr<io::Tileset> tileset, StreamerOptions options);
  ~TileStreamer();
  TileStreamer(const TileStreamer&) = delete;
  TileStreamer& operator=(const TileStreamer&) = delete;

  // One frame: integrates finished loads, selects tiles, evicts, cancels and schedules loads.
  // Returns the selection whose `render` tiles are all resident.
  const Selection& update(const View& view);
  // Blocks until something in flight finishes (or returns at once when nothing is).
  void wait_for_progress();
  bool idle() const;  // nothing queued or in flight (loads and pending children)
  // Something in flight has finished since the last update(), which will take it in: a front
  // end that draws only on change (the page) runs a frame then, not while loads are under way.
  bool has_results() const;

  const io::Tileset& tileset() const { return *tileset_; }
  // Content of a Loaded tile (all of its contents merged); nullptr otherwise.
  const std::vector<io::PointContent>* content(uint32_t tile) const;
  // What StreamerOptions::prepare made of a Loaded tile; nullptr otherwise (or without a hook).
  const PreparedTile* prepared(uint32_t tile) const;
  const std::vector<TileState>& states() const { return states_; }
  // Failed tiles since the last call; the streamer prints nothing itself, so each is reported
  // once, by the caller.
  std::vector<TileError> take_errors();
  // The decoders' warnings on loaded tiles' contents ("uri: text": skipped primitives, unknown
  // semantics), each tile's once, since the last call.
  std::vector<TileError> take_warnings();
  const std::vector<TileError>& errors() const { return all_errors_; }
  StreamerStats stats() const;
  // Takes effect from the next update(): a lower memory budget evicts unused tiles down to it, a
  // higher max_sse selects coarser tiles (the viewer's panel turns these knobs).
  void set_traversal_options(const TraversalOptions& traversal) { options_.traversal = traversal; }
  const TraversalOptions& traversal_options() const { return options_.traversal; }

 private:
  struct Job;
  struct Shared;
  std::shared_ptr<io::Tileset> tileset_;
  StreamerOptions options_;
  io::Fetcher fetcher_;
  std::vector<TileState> states_;
  std::vector<std::vector<io::PointContent>> contents_;
  std::vector<PreparedTile> prepared_;           // by tile, grown on demand (see release_prepared)
  std::vector<std::shared_ptr<Job>> jobs_;       // by tile, while Loading
  std::vector<std::shared_ptr<Job>> expanding_;  // reading pending children
  std::vector<LoadRequest> queue_;               // wanted, not started; most important first
  std::vector<LoadRequest> expand_queue_;        // pending children wanted, not started
  std::shared_ptr<Shared> shared_;
  std::unique_ptr<ThreadPool> pool_;
  Selection selection_;
  uint64_t frame_ = 0;
  StreamerStats stats_;
  std::vector<TileError> new_errors_, all_errors_, new_warnings_;
  std::vector<bool> warned_;         // by tile: its content warnings were handed out
  std::set<std::string> not_drawn_;  // content kinds warned about (once each)
  uint32_t in_flight_ = 0;

  void integrate();
  void start_jobs();
  void release_prepared(uint32_t tile);
  void evict(uint32_t tile);
  void grow();
  void make_resident(Job& job, uint64_t bytes);
};

}  // namespace stipple::tiles3d
