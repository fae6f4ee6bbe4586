// Render graph compile step and transient pool, without a GPU: culling, lifetimes, pool reuse,
// validation errors and the DOT dump.
#include <gtest/gtest.h>

#include <sstream>
#include <string>

#include "stipple/core/error.hpp"
#include "stipple/renderer/render_graph.hpp"

using namespace stipple;
using gpu::Access;
using gpu::CompiledGraph;
using gpu::PassKind;
using gpu::RenderGraph;

namespace {

const gpu::TextureDesc kColor{64, 32, WGPUTextureFormat_RGBA8Unorm,
                              WGPUTextureUsage_RenderAttachment | WGPUTextureUsage_TextureBinding};
const gpu::TextureDesc kDepth{64, 32, WGPUTextureFormat_Depth32Float,
                              WGPUTextureUsage_RenderAttachment};

void import_target(RenderGraph& g, std::string name = "target") {
  g.import_texture(std::move(name), nullptr, nullptr, kColor, Access::Writable);
}

std::string compile_error(RenderGraph& g) {
  try {
    g.compile();
  } catch (const Error& e) {
    return e.what();
  }
  return "(no error)";
}

std::vector<std::string> surviving(const RenderGraph& g) {
  std::vector<std::string> names;
  for (uint32_t p : g.plan().order) names.push_back(g.passes()[p].name);
  return names;
}

uint32_t resource(const RenderGraph& g, const std::string& name) {
  return g.plan().resource_index.at(name);
}

}  // namespace

TEST(RenderGraph, CullsChainsBackwardsFromOutputs) {
  RenderGraph g;
  import_target(g);
  // used chain: a -> b -> final (writes target); dead chain: x -> y (y's output never read).
  g.add_pass("a", PassKind::Compute, {}).create_buffer("a_out", {256, WGPUBufferUsage_Storage});
  g.add_pass("x", PassKind::Compute, {}).create_texture("x_out", kColor);
  g.add_pass("b", PassKind::Render, {}).read("a_out").create_texture("b_out", kColor);
  g.add_pass("y", PassKind::Render, {}).read("x_out").create_texture("y_out", kColor);
  g.add_pass("final", PassKind::Render, {}).read("b_out").write("target");
  // Reads the dead chain but is itself dead: culling propagates through it.
  g.add_pass("z", PassKind::Render, {}).read("y_out").read("b_out").create_texture("z_out", kColor);
  const CompiledGraph& plan = g.compile();
  EXPECT_EQ(surviving(g), (std::vector<std::string>{"a", "b", "final"}));
  EXPECT_EQ(plan.culled, (std::vector<bool>{false, true, false, true, false, true}));
  EXPECT_EQ(plan.timed_passes, 3u);
  // Transients of culled passes are never allocated.
  EXPECT_EQ(plan.first_use[resource(g, "x_out")], CompiledGraph::kNone);
  EXPECT_EQ(plan.first_use[resource(g, "z_out")], CompiledGraph::kNone);
}

TEST(RenderGraph, NothingSurvivesWithoutOutputs) {
  RenderGraph g;
  g.add_pass("a", PassKind::Render, {}).create_texture("t", kColor);
  g.add_pass("b", PassKind::Render, {}).read("t").create_texture("u", kColor);
  g.compile();
  EXPECT_TRUE(surviving(g).empty());
}

TEST(RenderGraph, KeepsSideEffectPassesAndWhatTheyRead) {
  RenderGraph g;
  g.add_pass("produce", PassKind::Compute, {})
      .create_buffer("stats", {64, WGPUBufferUsage_Storage});
  g.add_pass("readback", PassKind::Transfer, {}).read("stats").side_effect();
  g.add_pass("unused", PassKind::Compute, {}).create_buffer("junk", {64, WGPUBufferUsage_Storage});
  const CompiledGraph& plan = g.compile();
  EXPECT_EQ(surviving(g), (std::vector<std::string>{"produce", "readback"}));
  EXPECT_EQ(plan.timed_passes, 1u);  // transfer passes are not timed
}

TEST(RenderGraph, ReadOnlyImportsAreNotOutputs) {
  RenderGraph g;
  g.import_buffer("input", nullptr, {16, WGPUBufferUsage_Storage}, Access::ReadOnly);
  import_target(g);
  g.add_pass("reads_input_only", PassKind::Compute, {})
      .read("input")
      .create_buffer("tmp", {16, WGPUBufferUsage_Storage});
  g.add_pass("writes_target", PassKind::Render, {}).read("input").write("target");
  g.compile();
  EXPECT_EQ(surviving(g), (std::vector<std::string>{"writes_target"}));
}

TEST(RenderGraph, WritesKeepEarlierWritersAlive) {
  // "clear" creates, "draw" loads and adds to it, "compose" reads: all three are needed. A later
  // write nobody reads is culled.
  RenderGraph g;
  import_target(g);
  g.add_pass("clear", PassKind::Render, {}).create_texture("hdr", kColor);
  g.add_pass("draw", PassKind::Render, {}).write("hdr");
  g.add_pass("compose", PassKind::Render, {}).read("hdr").write("target");
  g.add_pass("late_draw", PassKind::Render, {}).write("hdr");
  g.compile();
  EXPECT_EQ(surviving(g), (std::vector<std::string>{"clear", "draw", "compose"}));
  const CompiledGraph& plan = g.plan();
  uint32_t hdr = resource(g, "hdr");
  EXPECT_EQ(plan.first_use[hdr], 0u);
  EXPECT_EQ(plan.last_use[hdr], 2u);  // the culled late_draw does not extend it
}

TEST(RenderGraph, LifetimesRunFromCreatorToLastReader) {
  RenderGraph g;
  import_target(g);
  g.add_pass("p0", PassKind::Render, {})
      .create_texture("gbuffer", kColor)
      .create_texture("depth", kDepth);
  g.add_pass("p1", PassKind::Compute, {}).read("depth").create_texture("ao", kColor);
  g.add_pass("p2", PassKind::Render, {}).read("gbuffer").read("ao").create_texture("lit", kColor);
  g.add_pass("p3", PassKind::Render, {}).read("lit").write("target");
  const CompiledGraph& plan = g.compile();
  auto life = [&](const char* name) {
    uint32_t r = resource(g, name);
    return std::pair{plan.first_use[r], plan.last_use[r]};
  };
  EXPECT_EQ(life("gbuffer"), (std::pair{0u, 2u}));
  EXPECT_EQ(life("depth"), (std::pair{0u, 1u}));
  EXPECT_EQ(life("ao"), (std::pair{1u, 2u}));
  EXPECT_EQ(life("lit"), (std::pair{2u, 3u}));
  EXPECT_EQ(plan.creator[resource(g, "ao")], 1u);
  EXPECT_EQ(plan.creator[resource(g, "target")], CompiledGraph::kNone);
  EXPECT_EQ(plan.allocate_before[0].size(), 2u);
  EXPECT_EQ(plan.release_after[1], (std::vector<uint32_t>{resource(g, "depth")}));
  EXPECT_EQ(plan.release_after[3], (std::vector<uint32_t>{resource(g, "lit")}));

  // "lit" is allocated before p2 while gbuffer and ao are still alive (released after p2), so
  // the first frame needs three colour textures and one depth texture.
  gpu::TransientPool pool;
  auto slots = gpu::assign_transients(plan, pool);
  EXPECT_EQ(pool.stats.textures_created, 4u);
  EXPECT_EQ(slots[resource(g, "target")], CompiledGraph::kNone);
  EXPECT_NE(slots[resource(g, "gbuffer")], slots[resource(g, "ao")]);
  for (const auto& slot : pool.slots) EXPECT_FALSE(slot.in_use);
}

TEST(RenderGraph, ReleasedTransientsAreReusedWithinAFrame) {
  RenderGraph g;
  import_target(g);
  g.add_pass("a", PassKind::Render, {}).create_texture("t1", kColor);
  g.add_pass("b", PassKind::Render, {}).read("t1").create_texture("t2", kColor);
  g.add_pass("c", PassKind::Render, {}).read("t2").create_texture("t3", kColor);
  g.add_pass("d", PassKind::Render, {}).read("t3").write("target");
  g.compile();
  gpu::TransientPool pool;
  auto slots = gpu::assign_transients(g.plan(), pool);
  // t1 dies after b, so t3 (allocated before c) takes its texture: ping-pong between two.
  EXPECT_EQ(pool.stats.textures_created, 2u);
  EXPECT_EQ(slots[resource(g, "t1")], slots[resource(g, "t3")]);
  EXPECT_NE(slots[resource(g, "t1")], slots[resource(g, "t2")]);
}

TEST(RenderGraph, PoolIsReusedAcrossFrames) {
  gpu::TransientPool pool;
  for (int frame = 0; frame < 3; ++frame) {
    // Rebuilt each frame, as a renderer would.
    RenderGraph g;
    import_target(g);
    g.add_pass("depth_pre", PassKind::Render, {}).create_texture("depth", kDepth);
    g.add_pass("points", PassKind::Render, {}).write("depth").create_texture("hdr", kColor);
    g.add_pass("cull", PassKind::Compute, {})
        .create_buffer("visible", {1024, WGPUBufferUsage_Storage});
    g.add_pass("compose", PassKind::Render, {}).read("hdr").read("visible").write("target");
    g.compile();
    gpu::assign_transients(g.plan(), pool);
    gpu::pool_end_frame(pool);
    EXPECT_EQ(pool.stats.textures_created, 2u) << "frame " << frame;
    EXPECT_EQ(pool.stats.buffers_created, 1u) << "frame " << frame;
    EXPECT_EQ(pool.stats.reused, 3u * frame) << "frame " << frame;
  }
  // A different size is a new texture; the old ones are evicted once idle long enough.
  for (int frame = 0; frame < 3; ++frame) {
    RenderGraph g;
    import_target(g);
    gpu::TextureDesc big = kDepth;
    big.width = 128;
    g.add_pass("points", PassKind::Render, {}).create_texture("depth", big).write("target");
    g.compile();
    gpu::assign_transients(g.plan(), pool);
    gpu::pool_end_frame(pool, 1);
  }
  EXPECT_EQ(pool.stats.textures_created, 3u);
  EXPECT_EQ(pool.slots.size(), 1u);
  EXPECT_EQ(pool.stats.evicted, 3u);
}

TEST(RenderGraph, ReportsReadsOfUnwrittenResources) {
  RenderGraph g;
  import_target(g);
  g.add_pass("compose", PassKind::Render, {}).read("hdr").write("target");
  std::string message = compile_error(g);
  EXPECT_NE(message.find("'compose'"), std::string::npos) << message;
  EXPECT_NE(message.find("'hdr'"), std::string::npos) << message;

  // Created, but by a later pass.
  g.add_pass("draw", PassKind::Render, {}).create_texture("hdr", kColor);
  message = compile_error(g);
  EXPECT_NE(message.find("pass 'compose' reads 'hdr' before pass 'draw' creates it"),
            std::string::npos)
      << message;

  RenderGraph self;
  self.add_pass("p", PassKind::Render, {}).create_texture("t", kColor).read("t");
  EXPECT_NE(compile_error(self).find("'t'"), std::string::npos);

  RenderGraph unknown_write;
  unknown_write.add_pass("p", PassKind::Render, {}).write("nowhere");
  message = compile_error(unknown_write);
  EXPECT_NE(message.find("pass 'p' writes 'nowhere'"), std::string::npos) << message;
}

TEST(RenderGraph, ReportsWritesToReadOnlyImports) {
  RenderGraph g;
  g.import_texture("history", nullptr, nullptr, kColor, Access::ReadOnly);
  g.add_pass("taa", PassKind::Render, {}).read("history").write("history").side_effect();
  std::string message = compile_error(g);
  EXPECT_NE(message.find("pass 'taa' writes 'history', which is imported read-only"),
            std::string::npos)
      << message;
}

// A target taken only just before execute() (a browser canvas's texture) is imported without
// objects and bound later, before or after compile(); the plan stays as compiled.
TEST(RenderGraph, BindsAnImportedTextureAfterThePassesAreAdded) {
  RenderGraph g;
  import_target(g, "color");
  g.import_buffer("counters", nullptr, {256, WGPUBufferUsage_Storage}, Access::Writable);
  g.add_pass("draw", PassKind::Render, {}).write("color");
  const auto texture = reinterpret_cast<WGPUTexture>(uintptr_t(0x10));
  const auto view = reinterpret_cast<WGPUTextureView>(uintptr_t(0x20));
  g.compile();
  g.bind_imported_texture("color", texture, view);
  EXPECT_TRUE(g.compiled());
  const gpu::GraphResource& bound = g.plan().resources[resource(g, "color")];
  EXPECT_EQ(bound.imported_texture, texture);
  EXPECT_EQ(bound.imported_view, view);
  // Recompiling keeps the objects.
  g.add_pass("late", PassKind::Render, {}).write("color");
  g.compile();
  EXPECT_EQ(g.plan().resources[resource(g, "color")].imported_view, view);

  for (const char* name : {"counters", "nowhere"}) {
    try {
      g.bind_imported_texture(name, texture, view);
      FAIL() << name << ": expected an error";
    } catch (const Error& e) {
      EXPECT_NE(
          std::string(e.what()).find(std::string("'") + name + "' is not an imported texture"),
          std::string::npos)
          << e.what();
    }
  }
}

TEST(RenderGraph, ReportsDuplicateNames) {
  RenderGraph passes;
  passes.add_pass("points", PassKind::Render, {});
  passes.add_pass("points", PassKind::Render, {});
  EXPECT_NE(compile_error(passes).find("duplicate pass name 'points'"), std::string::npos);

  RenderGraph imports;
  import_target(imports, "color");
  import_target(imports, "color");
  EXPECT_NE(compile_error(imports).find("'color' is imported twice"), std::string::npos);

  RenderGraph shadowing;
  import_target(shadowing, "color");
  shadowing.add_pass("p", PassKind::Render, {}).create_texture("color", kColor);
  std::string message = compile_error(shadowing);
  EXPECT_NE(message.find("pass 'p' creates 'color', the name of an imported resource"),
            std::string::npos)
      << message;
}

TEST(RenderGraph, ReportsResourcesCreatedTwice) {
  RenderGraph g;
  g.add_pass("first", PassKind::Render, {}).create_texture("depth", kDepth);
  g.add_pass("second", PassKind::Render, {}).create_texture("depth", kDepth);
  std::string message = compile_error(g);
  EXPECT_NE(message.find("'depth' is created twice, by pass 'first' and by pass 'second'"),
            std::string::npos)
      << message;

  RenderGraph same_pass;
  same_pass.add_pass("p", PassKind::Render, {}).create_texture("t", kColor).create_buffer("t", {4});
  EXPECT_NE(compile_error(same_pass).find("pass 'p' creates 't' twice"), std::string::npos);

  RenderGraph zero;
  zero.add_pass("p", PassKind::Render, {}).create_texture("t", {0, 4});
  EXPECT_NE(compile_error(zero).find("zero size"), std::string::npos);
}

TEST(RenderGraph, DumpsDot) {
  RenderGraph g;
  import_target(g);
  g.add_pass("clear", PassKind::Render, {}).create_texture("scratch", kColor);
  g.add_pass("copy", PassKind::Transfer, {}).read("scratch").write("target");
  g.add_pass("unused", PassKind::Compute, {}).create_buffer("junk", {64});
  std::ostringstream dot;
  g.dump_dot(dot);
  std::string text = dot.str();
  EXPECT_EQ(text.rfind("digraph render_graph {", 0), 0u) << text;
  EXPECT_NE(text.find("p0 [shape=box, label=\"clear\\n(render)\""), std::string::npos) << text;
  EXPECT_NE(text.find("p2 [shape=box, label=\"unused\\n(compute)\", style=\"dashed,filled\""),
            std::string::npos)
      << text;
  EXPECT_NE(text.find("r0 [shape=ellipse, label=\"target\\n64x32 rgba8unorm, imported\""),
            std::string::npos)
      << text;
  EXPECT_NE(text.find("p0 -> r1 [label=\"create\"]"), std::string::npos) << text;
  EXPECT_NE(text.find("r1 -> p1 [label=\"read\"]"), std::string::npos) << text;
  EXPECT_NE(text.find("p1 -> r0 [label=\"write\"]"), std::string::npos) << text;
  EXPECT_NE(text.find("p2 -> r2 [label=\"create\", style=dashed, color=grey]"), std::string::npos)
      << text;
  EXPECT_EQ(text.substr(text.size() - 2), "}\n");
}
