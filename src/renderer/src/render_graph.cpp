#include "stipple/renderer/render_graph.hpp"

#include <algorithm>
#include <ostream>
#include <set>

#include "stipple/core/error.hpp"

namespace stipple::gpu {

// ---- declaration ---------------------------------------------------------------------------

GraphPass& PassBuilder::pass() const {
  return graph_->passes_[pass_];
}

PassBuilder& PassBuilder::create_texture(std::string name, const TextureDesc& desc) {
  GraphResource r;
  r.name = name;
  r.kind = ResourceKind::Texture;
  r.texture = desc;
  pass().created.push_back(std::move(r));
  pass().creates.push_back(std::move(name));
  graph_->compiled_ = false;
  return *this;
}

PassBuilder& PassBuilder::create_buffer(std::string name, const BufferDesc& desc) {
  GraphResource r;
  r.name = name;
  r.kind = ResourceKind::Buffer;
  r.buffer = desc;
  pass().created.push_back(std::move(r));
  pass().creates.push_back(std::move(name));
  graph_->compiled_ = false;
  return *this;
}

PassBuilder& PassBuilder::read(std::string name) {
  pass().reads.push_back(std::move(name));
  graph_->compiled_ = false;
  return *this;
}

PassBuilder& PassBuilder::write(std::string name) {
  pass().writes.push_back(std::move(name));
  graph_->compiled_ = false;
  return *this;
}

PassBuilder& PassBuilder::side_effect() {
  pass().side_effect = true;
  graph_->compiled_ = false;
  return *this;
}

void RenderGraph::import_texture(std::string name, WGPUTexture texture, WGPUTextureView view,
                                 const TextureDesc& desc, Access access) {
  GraphResource r;
  r.name = std::move(name);
  r.kind = ResourceKind::Texture;
  r.texture = desc;
  r.imported = true;
  r.access = access;
  r.imported_texture = texture;
  r.imported_view = view;
  imports_.push_back(std::move(r));
  compiled_ = false;
}

void RenderGraph::import_buffer(std::string name, WGPUBuffer buffer, const BufferDesc& desc,
                                Access access) {
  GraphResource r;
  r.name = std::move(name);
  r.kind = ResourceKind::Buffer;
  r.buffer = desc;
  r.imported = true;
  r.access = access;
  r.imported_buffer = buffer;
  imports_.push_back(std::move(r));
  compiled_ = false;
}

void RenderGraph::bind_imported_texture(std::string_view name, WGPUTexture texture,
                                        WGPUTextureView view) {
  auto it = std::find_if(imports_.begin(), imports_.end(),
                         [&](const GraphResource& r) { return r.name == name; });
  if (it == imports_.end() || it->kind != ResourceKind::Texture)
    fail("render graph: '{}' is not an imported texture", name);
  it->imported_texture = texture;
  it->imported_view = view;
  // The compiled plan holds copies of the imports.
  if (auto r = plan_.resource_index.find(name); compiled_ && r != plan_.resource_index.end()) {
    plan_.resources[r->second].imported_texture = texture;
    plan_.resources[r->second].imported_view = view;
  }
}

PassBuilder RenderGraph::add_pass(std::string name, PassKind kind, PassExecute execute) {
  GraphPass pass;
  pass.name = std::move(name);
  pass.kind = kind;
  pass.execute = std::move(execute);
  passes_.push_back(std::move(pass));
  compiled_ = false;
  return PassBuilder(*this, uint32_t(passes_.size() - 1));
}

// ---- compile -------------------------------------------------------------------------------

const CompiledGraph& RenderGraph::compile() {
  constexpr uint32_t kNone = CompiledGraph::kNone;
  CompiledGraph plan;
  const uint32_t pass_count = uint32_t(passes_.size());

  std::set<std::string_view> pass_names;
  for (const GraphPass& pass : passes_)
    if (!pass_names.insert(pass.name).second)
      fail("render graph: duplicate pass name '{}'", pass.name);

  for (const GraphResource& r : imports_) {
    if (plan.resource_index.count(r.name))
      fail("render graph: resource '{}' is imported twice", r.name);
    plan.resource_index.emplace(r.name, uint32_t(plan.resources.size()));
    plan.resources.push_back(r);
    plan.creator.push_back(kNone);
  }

  // Every pass's resources as indices; resources become visible after the pass that creates them.
  std::vector<std::vector<uint32_t>> reads(pass_count), writes(pass_count), creates(pass_count);
  auto creator_name = [&](uint32_t r) { return passes_[plan.creator[r]].name; };
  for (uint32_t p = 0; p < pass_count; ++p) {
    const GraphPass& pass = passes_[p];
    for (const std::string& name : pass.reads) {
      auto it = plan.resource_index.find(name);
      if (it == plan.resource_index.end()) {
        // Say whether a later pass creates it: the usual cause is pass order.
        for (uint32_t q = p + 1; q < pass_count; ++q)
          if (std::count(passes_[q].creates.begin(), passes_[q].creates.end(), name))
            fail("render graph: pass '{}' reads '{}' before pass '{}' creates it", pass.name, name,
                 passes_[q].name);
        fail(
            "render graph: pass '{}' reads '{}', which is neither imported nor created by an "
            "earlier pass",
            pass.name, name);
      }
      reads[p].push_back(it->second);
    }
    for (const std::string& name : pass.writes) {
      if (std::count(pass.creates.begin(), pass.creates.end(), name)) continue;  // implied
      auto it = plan.resource_index.find(name);
      if (it == plan.resource_index.end())
        fail(
            "render graph: pass '{}' writes '{}', which is neither imported nor created by an "
            "earlier pass",
            pass.name, name);
      const GraphResource& r = plan.resources[it->second];
      if (r.imported && r.access == Access::ReadOnly)
        fail("render graph: pass '{}' writes '{}', which is imported read-only", pass.name, name);
      writes[p].push_back(it->second);
    }
    for (const GraphResource& created : pass.created) {
      auto it = plan.resource_index.find(created.name);
      if (it != plan.resource_index.end()) {
        uint32_t r = it->second;
        if (plan.resources[r].imported)
          fail("render graph: pass '{}' creates '{}', the name of an imported resource", pass.name,
               created.name);
        if (plan.creator[r] == p)
          fail("render graph: pass '{}' creates '{}' twice", pass.name, created.name);
        fail("render graph: resource '{}' is created twice, by pass '{}' and by pass '{}'",
             created.name, creator_name(r), pass.name);
      }
      if (created.kind == ResourceKind::Texture &&
          (created.texture.width == 0 || created.texture.height == 0))
        fail("render graph: pass '{}' creates texture '{}' with a zero size", pass.name,
             created.name);
      if (created.kind == ResourceKind::Buffer && created.buffer.size == 0)
        fail("render graph: pass '{}' creates buffer '{}' with a zero size", pass.name,
             created.name);
      uint32_t r = uint32_t(plan.resources.size());
      plan.resource_index.emplace(created.name, r);
      plan.resources.push_back(created);
      plan.creator.push_back(p);
      creates[p].push_back(r);
    }
  }

  // Culling, backwards: a pass lives when it has a side effect, writes an imported writable
  // resource, or writes/creates something a living later pass uses. A write keeps the resource
  // needed by earlier passes too: it may load what they left (render passes with LoadOp_Load).
  const uint32_t resource_count = uint32_t(plan.resources.size());
  std::vector<bool> needed(resource_count, false);
  plan.culled.assign(pass_count, true);
  for (uint32_t p = pass_count; p-- > 0;) {
    bool alive = passes_[p].side_effect;
    for (const auto* outputs : {&writes[p], &creates[p]})
      for (uint32_t r : *outputs)
        if (needed[r] ||
            (plan.resources[r].imported && plan.resources[r].access == Access::Writable))
          alive = true;
    if (!alive) continue;
    plan.culled[p] = false;
    for (uint32_t r : reads[p]) needed[r] = true;
    for (uint32_t r : writes[p]) needed[r] = true;
  }

  // Lifetimes of transients over the surviving passes.
  plan.first_use.assign(resource_count, kNone);
  plan.last_use.assign(resource_count, kNone);
  plan.allocate_before.assign(pass_count, {});
  plan.release_after.assign(pass_count, {});
  for (uint32_t p = 0; p < pass_count; ++p) {
    if (plan.culled[p]) continue;
    plan.order.push_back(p);
    if (passes_[p].kind != PassKind::Transfer) plan.timed_passes++;
    for (const auto* used : {&creates[p], &reads[p], &writes[p]})
      for (uint32_t r : *used) {
        if (plan.resources[r].imported) continue;
        if (plan.first_use[r] == kNone) plan.first_use[r] = p;
        plan.last_use[r] = p;
      }
  }
  for (uint32_t r = 0; r < resource_count; ++r) {
    if (plan.first_use[r] == kNone) continue;
    plan.allocate_before[plan.first_use[r]].push_back(r);
    plan.release_after[plan.last_use[r]].push_back(r);
  }

  plan_ = std::move(plan);
  compiled_ = true;
  return plan_;
}

// ---- transient pool ------------------------------------------------------------------------

uint32_t pool_acquire(TransientPool& pool, const GraphResource& resource) {
  for (uint32_t i = 0; i < pool.slots.size(); ++i) {
    TransientPool::Slot& slot = pool.slots[i];
    if (slot.in_use || slot.kind != resource.kind) continue;
    bool same = resource.kind == ResourceKind::Texture ? slot.texture == resource.texture
                                                       : slot.buffer == resource.buffer;
    if (!same) continue;
    slot.in_use = true;
    slot.last_used_frame = pool.frame;
    pool.stats.reused++;
    return i;
  }
  TransientPool::Slot slot;
  slot.kind = resource.kind;
  slot.texture = resource.texture;
  slot.buffer = resource.buffer;
  slot.in_use = true;
  slot.last_used_frame = pool.frame;
  if (resource.kind == ResourceKind::Texture)
    pool.stats.textures_created++;
  else
    pool.stats.buffers_created++;
  pool.slots.push_back(std::move(slot));
  return uint32_t(pool.slots.size() - 1);
}

void pool_release(TransientPool& pool, uint32_t slot) {
  if (slot < pool.slots.size()) pool.slots[slot].in_use = false;
}

void pool_end_frame(TransientPool& pool, uint32_t max_idle_frames) {
  // Slot indices only matter within a frame, so eviction may compact the list.
  auto stale = [&](const TransientPool::Slot& s) {
    return !s.in_use && pool.frame - s.last_used_frame > max_idle_frames;
  };
  auto end = std::remove_if(pool.slots.begin(), pool.slots.end(), stale);
  pool.stats.evicted += uint64_t(pool.slots.end() - end);
  pool.slots.erase(end, pool.slots.end());
  pool.frame++;
}

std::vector<uint32_t> assign_transients(const CompiledGraph& plan, TransientPool& pool) {
  std::vector<uint32_t> slots(plan.resources.size(), CompiledGraph::kNone);
  for (uint32_t p : plan.order) {
    for (uint32_t r : plan.allocate_before[p]) slots[r] = pool_acquire(pool, plan.resources[r]);
    for (uint32_t r : plan.release_after[p]) pool_release(pool, slots[r]);
  }
  return slots;
}

// ---- execution -----------------------------------------------------------------------------

std::string_view PassContext::pass_name() const {
  return graph_->passes_[pass_].name;
}

uint32_t PassContext::declared(std::string_view name) const {
  const GraphPass& pass = graph_->passes_[pass_];
  auto listed = [&](const std::vector<std::string>& names) {
    return std::find(names.begin(), names.end(), name) != names.end();
  };
  if (!listed(pass.creates) && !listed(pass.reads) && !listed(pass.writes))
    fail("render graph: pass '{}' uses '{}' without declaring it", pass.name, name);
  return graph_->plan_.resource_index.find(name)->second;
}

WGPUTexture PassContext::texture(std::string_view name) const {
  uint32_t r = declared(name);
  const GraphResource& res = graph_->plan_.resources[r];
  if (res.kind != ResourceKind::Texture)
    fail("render graph: pass '{}': '{}' is not a texture", pass_name(), name);
  return res.imported ? res.imported_texture : pool_->slots[(*slots_)[r]].gpu_texture.get();
}

WGPUTextureView PassContext::view(std::string_view name) const {
  uint32_t r = declared(name);
  const GraphResource& res = graph_->plan_.resources[r];
  if (res.kind != ResourceKind::Texture)
    fail("render graph: pass '{}': '{}' is not a texture", pass_name(), name);
  return res.imported ? res.imported_view : pool_->slots[(*slots_)[r]].gpu_view.get();
}

WGPUBuffer PassContext::buffer(std::string_view name) const {
  uint32_t r = declared(name);
  const GraphResource& res = graph_->plan_.resources[r];
  if (res.kind != ResourceKind::Buffer)
    fail("render graph: pass '{}': '{}' is not a buffer", pass_name(), name);
  return res.imported ? res.imported_buffer : pool_->slots[(*slots_)[r]].gpu_buffer.get();
}

const TextureDesc& PassContext::texture_desc(std::string_view name) const {
  return graph_->plan_.resources[declared(name)].texture;
}

const BufferDesc& PassContext::buffer_desc(std::string_view name) const {
  return graph_->plan_.resources[declared(name)].buffer;
}

const WGPUPassTimestampWrites* PassContext::timestamp_writes() {
  if (!timer_ || timer_index_ == CompiledGraph::kNone) return nullptr;
  used_timestamps_ = true;
  return pass_timestamps(*timer_, timer_index_, timestamps_);
}

RenderPassEncoder PassContext::begin_render_pass(WGPURenderPassDescriptor desc) {
  desc.timestampWrites = timestamp_writes();
  if (desc.label.data == nullptr) desc.label = to_view(pass_name());
  return RenderPassEncoder(wgpuCommandEncoderBeginRenderPass(encoder_, &desc));
}

ComputePassEncoder PassContext::begin_compute_pass() {
  WGPUComputePassDescriptor desc = WGPU_COMPUTE_PASS_DESCRIPTOR_INIT;
  desc.label = to_view(pass_name());
  desc.timestampWrites = timestamp_writes();
  return ComputePassEncoder(wgpuCommandEncoderBeginComputePass(encoder_, &desc));
}

void draw_fullscreen(PassContext& pc, WGPUTextureView target, WGPURenderPipeline pipeline,
                     std::initializer_list<BoundGroup> groups, std::optional<WGPUColor> clear) {
  WGPURenderPassColorAttachment color = WGPU_RENDER_PASS_COLOR_ATTACHMENT_INIT;
  color.view = target;
  color.loadOp = clear ? WGPULoadOp_Clear : WGPULoadOp_Load;
  color.storeOp = WGPUStoreOp_Store;
  if (clear) color.clearValue = *clear;
  WGPURenderPassDescriptor desc = WGPU_RENDER_PASS_DESCRIPTOR_INIT;
  desc.colorAttachmentCount = 1;
  desc.colorAttachments = &color;
  RenderPassEncoder pass = pc.begin_render_pass(desc);
  wgpuRenderPassEncoderSetPipeline(pass.get(), pipeline);
  set_bind_groups(pass.get(), groups);
  wgpuRenderPassEncoderDraw(pass.get(), 3, 1, 0, 0);
  wgpuRenderPassEncoderEnd(pass.get());
}

void RenderGraph::add_prepare(std::function<void(Context&)> prepare) {
  prepares_.push_back(std::move(prepare));
}

void RenderGraph::prepare(Context& ctx) {
  // By index: a prepare may add another.
  for (; prepared_ < prepares_.size(); ++prepared_) prepares_[prepared_](ctx);
}

void RenderGraph::execute(Context& ctx, TransientPool& pool, PassTimer* timer) {
  prepare(ctx);
  if (!compiled_) compile();
  for (const GraphResource& r : plan_.resources)
    if (r.imported && r.kind == ResourceKind::Texture && (!r.imported_texture || !r.imported_view))
      fail("render graph: the imported texture '{}' has no texture bound", r.name);
  std::vector<uint32_t> slots = assign_transients(plan_, pool);
  // New slots get their GPU objects now; reused ones keep theirs.
  for (uint32_t r = 0; r < slots.size(); ++r) {
    if (slots[r] == CompiledGraph::kNone) continue;
    TransientPool::Slot& slot = pool.slots[slots[r]];
    const GraphResource& res = plan_.resources[r];
    if (slot.kind == ResourceKind::Texture && !slot.gpu_texture) {
      slot.gpu_texture = create_texture_2d(ctx, slot.texture.width, slot.texture.height,
                                           slot.texture.format, slot.texture.usage, res.name);
      slot.gpu_view = create_view(slot.gpu_texture);
    } else if (slot.kind == ResourceKind::Buffer && !slot.gpu_buffer) {
      slot.gpu_buffer = create_buffer(ctx, slot.buffer.size, slot.buffer.usage, res.name);
    }
  }

  bool timing = timer && timer->enabled;
  timer_index_.assign(passes_.size(), CompiledGraph::kNone);
  used_timestamps_.assign(passes_.size(), false);
  uint32_t timed = 0;
  if (timing)
    for (uint32_t p : plan_.order)
      if (passes_[p].kind != PassKind::Transfer && timed < timer->capacity)
        timer_index_[p] = timed++;

  WGPUCommandEncoderDescriptor enc_desc = WGPU_COMMAND_ENCODER_DESCRIPTOR_INIT;
  enc_desc.label = to_view("render-graph");
  CommandEncoder encoder(wgpuDeviceCreateCommandEncoder(ctx.device.get(), &enc_desc));
  for (uint32_t p : plan_.order) {
    PassContext pc;
    pc.ctx_ = &ctx;
    pc.encoder_ = encoder.get();
    pc.graph_ = this;
    pc.slots_ = &slots;
    pc.pool_ = &pool;
    pc.pass_ = p;
    pc.timer_ = timing ? timer : nullptr;
    pc.timer_index_ = timer_index_[p];
    if (passes_[p].execute) passes_[p].execute(pc);
    used_timestamps_[p] = pc.used_timestamps_;
    // A timed pass that recorded nothing (say, no points to draw) still writes its two
    // timestamps, from an empty compute pass: resolving queries never written blocks on some
    // drivers (NVIDIA's Vulkan driver waits for them for ever; lavapipe returns zeros). Its
    // time is still left out of read_pass_times.
    if (pc.timer_ && pc.timer_index_ != CompiledGraph::kNone && !pc.used_timestamps_) {
      ComputePassEncoder empty = pc.begin_compute_pass();
      wgpuComputePassEncoderEnd(empty.get());
    }
  }
  if (timing && timed > 0) resolve_pass_timer(*timer, encoder.get(), timed);
  CommandBuffer commands(wgpuCommandEncoderFinish(encoder.get(), nullptr));
  WGPUCommandBuffer raw = commands.get();
  wgpuQueueSubmit(ctx.queue.get(), 1, &raw);
  pool_end_frame(pool);
  ctx.check("executing the render graph");
}

std::map<std::string, double> RenderGraph::read_pass_times(Context& ctx, PassTimer& timer) const {
  std::map<std::string, double> result;
  if (!timer.enabled) return result;
  std::vector<double> ms = gpu::read_pass_times(ctx, timer);
  for (uint32_t p = 0; p < timer_index_.size(); ++p)
    if (timer_index_[p] != CompiledGraph::kNone && used_timestamps_[p])
      result[passes_[p].name] = ms[timer_index_[p]];
  return result;
}

std::vector<std::string> RenderGraph::timed_pass_names(const PassTimer& timer) const {
  std::vector<std::string> names(timer.enabled ? timer.capacity : 0);
  for (uint32_t p = 0; p < timer_index_.size(); ++p)
    if (timer_index_[p] < names.size() && used_timestamps_[p])
      names[timer_index_[p]] = passes_[p].name;
  return names;
}

// ---- Graphviz ------------------------------------------------------------------------------

namespace {
std::string dot_escape(std::string_view s) {
  std::string out;
  for (char c : s) {
    if (c == '"' || c == '\\') out += '\\';
    out += c;
  }
  return out;
}

std::string texture_format_name(WGPUTextureFormat f) {
  switch (f) {
    case WGPUTextureFormat_RGBA8Unorm:
      return "rgba8unorm";
    case WGPUTextureFormat_BGRA8Unorm:
      return "bgra8unorm";
    case WGPUTextureFormat_RGBA16Float:
      return "rgba16float";
    case WGPUTextureFormat_RGBA32Float:
      return "rgba32float";
    case WGPUTextureFormat_R32Float:
      return "r32float";
    case WGPUTextureFormat_R32Uint:
      return "r32uint";
    case WGPUTextureFormat_Depth32Float:
      return "depth32float";
    case WGPUTextureFormat_Depth24Plus:
      return "depth24plus";
    default:
      return fmt::format("format 0x{:x}", uint32_t(f));
  }
}
}  // namespace

void RenderGraph::dump_dot(std::ostream& out) {
  if (!compiled_) compile();
  out << "digraph render_graph {\n  rankdir=LR;\n  node [fontname=\"sans-serif\"];\n";
  for (uint32_t p = 0; p < passes_.size(); ++p) {
    const GraphPass& pass = passes_[p];
    const char* kind = pass.kind == PassKind::Render    ? "render"
                       : pass.kind == PassKind::Compute ? "compute"
                                                        : "transfer";
    out << "  p" << p << " [shape=box, label=\"" << dot_escape(pass.name) << "\\n(" << kind
        << (pass.side_effect ? ", side effect" : "") << ")\"";
    if (plan_.culled[p])
      out << ", style=\"dashed,filled\", fillcolor=\"#dddddd\", color=grey, fontcolor=grey";
    else
      out << ", style=filled, fillcolor=\"#cfe2ff\"";
    out << "];\n";
  }
  for (uint32_t r = 0; r < plan_.resources.size(); ++r) {
    const GraphResource& res = plan_.resources[r];
    std::string desc = res.kind == ResourceKind::Texture
                           ? fmt::format("{}x{} {}", res.texture.width, res.texture.height,
                                         texture_format_name(res.texture.format))
                           : fmt::format("{} bytes", res.buffer.size);
    if (res.imported)
      desc += res.access == Access::ReadOnly ? ", imported read-only" : ", imported";
    out << "  r" << r << " [shape=ellipse, label=\"" << dot_escape(res.name) << "\\n"
        << dot_escape(desc) << "\"";
    if (res.imported)
      out << ", peripheries=2";
    else if (plan_.first_use[r] == CompiledGraph::kNone)
      out << ", style=dashed, color=grey, fontcolor=grey";
    out << "];\n";
  }
  for (uint32_t p = 0; p < passes_.size(); ++p) {
    const GraphPass& pass = passes_[p];
    const char* culled = plan_.culled[p] ? ", style=dashed, color=grey" : "";
    auto index = [&](const std::string& name) { return plan_.resource_index.at(name); };
    for (const std::string& name : pass.creates)
      out << "  p" << p << " -> r" << index(name) << " [label=\"create\"" << culled << "];\n";
    for (const std::string& name : pass.writes)
      if (!std::count(pass.creates.begin(), pass.creates.end(), name))
        out << "  p" << p << " -> r" << index(name) << " [label=\"write\"" << culled << "];\n";
    for (const std::string& name : pass.reads)
      out << "  r" << index(name) << " -> p" << p << " [label=\"read\"" << culled << "];\n";
  }
  out << "}\n";
}

}  // namespace stipple::gpu
