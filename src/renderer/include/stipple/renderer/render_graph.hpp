#pragma once
// A render graph (seed 000, sec. 3.4): passes declare the resources they create, read and write
// by name, with a callback that records commands. compile() culls passes whose outputs are never
// read (backwards from the imported outputs) and computes each transient's lifetime; execute()
// takes transients from a pool that lives across frames, runs the surviving passes in insertion
// order and submits them as one command buffer.
//
// compile() and the pool bookkeeping are plain CPU code, testable without a device.
#include <cstdint>
#include <functional>
#include <iosfwd>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "stipple/renderer/gpu.hpp"
#include "stipple/renderer/gpu_timer.hpp"

namespace stipple::gpu {

struct TextureDesc {
  uint32_t width = 0, height = 0;
  WGPUTextureFormat format = WGPUTextureFormat_RGBA8Unorm;
  WGPUTextureUsage usage = WGPUTextureUsage_RenderAttachment;
  bool operator==(const TextureDesc&) const = default;
};

struct BufferDesc {
  uint64_t size = 0;
  WGPUBufferUsage usage = WGPUBufferUsage_Storage;
  bool operator==(const BufferDesc&) const = default;
};

enum class ResourceKind { Texture, Buffer };
enum class Access { ReadOnly, Writable };
// Render and compute passes get timestamp writes when timing is on; transfer passes (copies,
// clears of buffers) cannot carry them.
enum class PassKind { Render, Compute, Transfer };

class PassContext;
using PassExecute = std::function<void(PassContext&)>;

struct GraphResource {
  std::string name;
  ResourceKind kind = ResourceKind::Texture;
  TextureDesc texture;  // kind == Texture
  BufferDesc buffer;    // kind == Buffer
  bool imported = false;
  Access access = Access::Writable;  // imported only
  // Imported objects (not owned).
  WGPUTexture imported_texture = nullptr;
  WGPUTextureView imported_view = nullptr;
  WGPUBuffer imported_buffer = nullptr;
};

struct GraphPass {
  std::string name;
  PassKind kind = PassKind::Render;
  PassExecute execute;
  bool side_effect = false;  // never culled (readbacks, queries, work the graph cannot see)
  std::vector<std::string> creates, reads, writes;  // resource names, in declaration order
  std::vector<GraphResource> created;               // descriptions of what it creates
};

// What compile() decides; indices are insertion indices into the graph's passes / resources.
struct CompiledGraph {
  static constexpr uint32_t kNone = UINT32_MAX;
  std::vector<uint32_t> order;           // surviving passes, in insertion order
  std::vector<bool> culled;              // per pass
  std::vector<GraphResource> resources;  // imported first, then transients in creation order
  std::map<std::string, uint32_t, std::less<>> resource_index;
  // Per resource: the creating pass (kNone for imported ones), and for transients of surviving
  // passes the first and last surviving pass that uses it (kNone when it is never allocated).
  std::vector<uint32_t> creator, first_use, last_use;
  // Per pass: transients to allocate before it runs and to release after it ran.
  std::vector<std::vector<uint32_t>> allocate_before, release_after;
  uint32_t timed_passes = 0;  // surviving render/compute passes
};

// Transient textures and buffers kept across frames: a released resource goes back to the pool
// and the next request with the same description (this frame or a later one) reuses it.
struct TransientPool {
  struct Slot {
    ResourceKind kind = ResourceKind::Texture;
    TextureDesc texture;
    BufferDesc buffer;
    bool in_use = false;
    uint64_t last_used_frame = 0;
    Texture gpu_texture;  // null until execute() creates it (or in CPU-only use)
    TextureView gpu_view;
    Buffer gpu_buffer;
  };
  std::vector<Slot> slots;
  uint64_t frame = 0;
  struct Stats {
    uint64_t textures_created = 0, buffers_created = 0;
    uint64_t reused = 0;  // requests served by an existing slot
    uint64_t evicted = 0;
  } stats;
};

// Takes a free slot matching the description, or adds a new one; returns its index.
uint32_t pool_acquire(TransientPool& pool, const GraphResource& resource);
void pool_release(TransientPool& pool, uint32_t slot);
// Ends a frame: drops slots unused for more than `max_idle_frames` frames.
void pool_end_frame(TransientPool& pool, uint32_t max_idle_frames = 8);
// Walks the compiled passes, acquiring each transient before its first use and releasing it
// after its last; returns the slot of every resource (kNone for imported or unused ones). The
// CPU half of execute().
std::vector<uint32_t> assign_transients(const CompiledGraph& plan, TransientPool& pool);

class RenderGraph;

// What a pass callback gets: the frame's command encoder and its declared resources.
class PassContext {
 public:
  Context& gpu() const { return *ctx_; }
  WGPUCommandEncoder encoder() const { return encoder_; }
  std::string_view pass_name() const;
  // The resources this pass declared (create/read/write); throws for any other name.
  WGPUTexture texture(std::string_view name) const;
  WGPUTextureView view(std::string_view name) const;
  WGPUBuffer buffer(std::string_view name) const;
  const TextureDesc& texture_desc(std::string_view name) const;
  const BufferDesc& buffer_desc(std::string_view name) const;
  // The pass's timestamp writes for its descriptor, or null when timing is off or the pass is a
  // transfer pass. The begin_* helpers fill them in.
  const WGPUPassTimestampWrites* timestamp_writes();
  RenderPassEncoder begin_render_pass(WGPURenderPassDescriptor desc);
  ComputePassEncoder begin_compute_pass();

 private:
  friend class RenderGraph;
  PassContext() = default;
  uint32_t declared(std::string_view name) const;
  Context* ctx_ = nullptr;
  WGPUCommandEncoder encoder_ = nullptr;
  const RenderGraph* graph_ = nullptr;
  const std::vector<uint32_t>* slots_ = nullptr;
  TransientPool* pool_ = nullptr;
  uint32_t pass_ = 0;
  PassTimer* timer_ = nullptr;
  uint32_t timer_index_ = CompiledGraph::kNone;
  WGPUPassTimestampWrites timestamps_{};
  bool used_timestamps_ = false;
};

// Builder for one pass: add_pass(...).create_texture(...).read(...).write(...).
class PassBuilder {
 public:
  PassBuilder& create_texture(std::string name, const TextureDesc& desc);
  PassBuilder& create_buffer(std::string name, const BufferDesc& desc);
  PassBuilder& read(std::string name);
  PassBuilder& write(std::string name);
  PassBuilder& side_effect();

 private:
  friend class RenderGraph;
  PassBuilder(RenderGraph& graph, uint32_t pass) : graph_(&graph), pass_(pass) {}
  GraphPass& pass() const;
  RenderGraph* graph_;
  uint32_t pass_;  // an index: the graph's pass list may grow while a builder is held
};

// Records a full-screen draw (3 vertices) of `pipeline` into `target`, a view of a texture the
// pass declared: loaded and kept, or cleared to `clear` first; `groups` bound at 0, 1, ...
void draw_fullscreen(PassContext& pc, WGPUTextureView target, WGPURenderPipeline pipeline,
                     std::initializer_list<BoundGroup> groups = {},
                     std::optional<WGPUColor> clear = std::nullopt);

class RenderGraph {
 public:
  // Resources made outside the graph. Writable imports are the graph's outputs: passes that
  // write them are kept.
  void import_texture(std::string name, WGPUTexture texture, WGPUTextureView view,
                      const TextureDesc& desc, Access access);
  void import_buffer(std::string name, WGPUBuffer buffer, const BufferDesc& desc, Access access);
  // Gives an imported texture its objects after the passes are added (imported with null ones),
  // or replaces them; the plan does not change. For a target acquired only just before
  // execute(): a browser canvas's texture expires whenever the page's thread yields, which the
  // systems that add passes may do (shader compilation, buffer mapping). Throws stipple::Error
  // for a name that is no imported texture.
  void bind_imported_texture(std::string_view name, WGPUTexture texture, WGPUTextureView view);
  PassBuilder add_pass(std::string name, PassKind kind, PassExecute execute);
  // Work a frame needs before any pass runs, outside the command encoder: making pipelines the
  // first time a frame needs them, which waits for their validation and so may yield the
  // browser's thread (a late target's texture is taken after it: bind_imported_texture).
  // prepare() runs those added since it last ran, in order; execute() runs any left.
  void add_prepare(std::function<void(Context&)> prepare);
  void prepare(Context& ctx);

  // Validates and plans; throws stipple::Error naming the pass and resource for: a read of a
  // resource no earlier pass created (and not imported), a write to a read-only import or to a
  // resource not created yet, duplicate pass or resource names, a resource created twice.
  const CompiledGraph& compile();
  const CompiledGraph& plan() const { return plan_; }
  bool compiled() const { return compiled_; }
  const std::vector<GraphPass>& passes() const { return passes_; }

  // Compiles if needed, runs the surviving passes into one command encoder and submits it.
  // Throws stipple::Error for an imported texture that has no objects yet.
  // With an enabled timer, render/compute passes get timestamp writes (in order; passes beyond
  // its capacity are not timed).
  void execute(Context& ctx, TransientPool& pool, PassTimer* timer = nullptr);
  // GPU milliseconds per timed pass of the last execute() (blocks until the frame is done);
  // empty when timing is off. Passes that never used their timestamp writes are left out.
  std::map<std::string, double> read_pass_times(Context& ctx, PassTimer& timer) const;
  // For the timer of the last execute(): the pass that wrote each of its query pairs ("" where
  // none did; passes that never used their timestamp writes are left out), for
  // pass_timer_submitted.
  std::vector<std::string> timed_pass_names(const PassTimer& timer) const;

  // Graphviz DOT of the compiled graph: passes as boxes (culled ones grey and dashed), resources
  // as ellipses (imported ones doubled), edges for create/write (pass -> resource) and read
  // (resource -> pass).
  void dump_dot(std::ostream& out);

 private:
  friend class PassContext;
  friend class PassBuilder;
  std::vector<GraphResource> imports_;
  std::vector<GraphPass> passes_;
  std::vector<std::function<void(Context&)>> prepares_;
  size_t prepared_ = 0;  // prepares_ run so far
  CompiledGraph plan_;
  bool compiled_ = false;
  std::vector<uint32_t> timer_index_;  // per pass, from the last execute()
  std::vector<bool> used_timestamps_;
};

}  // namespace stipple::gpu
