// The engine core: ECS, hooks, relations, render-world sync, stages, plugins, pipelining.
#include <algorithm>
#include <atomic>
#include <chrono>
#include <semaphore>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

#include <gtest/gtest.h>

#include <glm/gtc/quaternion.hpp>

#include "stipple/engine/plugins.hpp"
#include "stipple/engine/registry.hpp"
#include "stipple/engine/relation.hpp"

using namespace stipple;
using namespace std::chrono_literals;

namespace {

struct Position {
  double x = 0;
};
struct Velocity {
  double dx = 0;
};
struct Mass {
  double kg = 0;
};
struct Tag {};

std::string error_of(const std::function<void()>& fn) {
  try {
    fn();
  } catch (const Error& e) {
    return e.what();
  }
  return "";
}

}  // namespace

// ---------------------------------------------------------------------------------------- ECS

TEST(Ecs, CreateDestroyRecyclesWithNewVersion) {
  Registry r;
  Entity a = r.create();
  Entity b = r.create();
  EXPECT_NE(a, b);
  EXPECT_EQ(r.size(), 2u);
  r.emplace<Position>(a, 1.0);
  EXPECT_TRUE(r.destroy(a));
  EXPECT_FALSE(r.alive(a));
  EXPECT_FALSE(r.destroy(a));  // stale handle: no-op
  Entity c = r.create();
  EXPECT_EQ(c.index, a.index);          // slot recycled...
  EXPECT_EQ(c.version, a.version + 1);  // ...with a new version
  EXPECT_TRUE(r.alive(c));
  EXPECT_FALSE(r.alive(a));
  EXPECT_FALSE(r.has<Position>(a));
  EXPECT_FALSE(r.has<Position>(c));  // components do not leak into the new entity
  EXPECT_EQ(r.try_get<Position>(a), nullptr);
  EXPECT_THROW(r.get<Position>(a), Error);
  EXPECT_THROW(r.emplace<Position>(a, 2.0), Error);  // cannot add to a stale handle
  EXPECT_FALSE(r.remove<Position>(a));
  EXPECT_TRUE(r.alive(b));
  EXPECT_EQ(r.size(), 2u);
  EXPECT_FALSE(r.alive(kNullEntity));
}

TEST(Ecs, EmplaceGetRemove) {
  Registry r;
  Entity e = r.create();
  r.emplace<Position>(e, 3.0);
  r.emplace<Tag>(e);
  EXPECT_TRUE((r.has<Position, Tag>(e)));
  EXPECT_FALSE((r.has<Position, Velocity>(e)));
  EXPECT_EQ(r.get<Position>(e).x, 3.0);
  EXPECT_THROW(r.emplace<Position>(e, 4.0), Error);  // already there
  r.emplace_or_replace(e, Position{5.0});
  EXPECT_EQ(r.get<Position>(e).x, 5.0);
  r.insert_or_assign(e, Position{6.0});
  EXPECT_EQ(r.get<Position>(e).x, 6.0);
  EXPECT_TRUE(r.remove<Position>(e));
  EXPECT_FALSE(r.remove<Position>(e));
  EXPECT_FALSE(r.has<Position>(e));
  EXPECT_TRUE(r.has<Tag>(e));
}

TEST(Ecs, SwapAndPopKeepsOtherComponents) {
  Registry r;
  std::vector<Entity> es;
  for (int i = 0; i < 10000; ++i) {  // spans several sparse pages
    es.push_back(r.create());
    r.emplace<Position>(es.back(), double(i));
  }
  for (int i = 0; i < 10000; i += 3) r.remove<Position>(es[i]);
  for (int i = 0; i < 10000; ++i) {
    if (i % 3 == 0) {
      EXPECT_FALSE(r.has<Position>(es[i]));
    } else {
      ASSERT_TRUE(r.has<Position>(es[i]));
      EXPECT_EQ(r.get<Position>(es[i]).x, double(i));
    }
  }
  EXPECT_EQ(r.count<Position>(), 10000u - 3334u);
}

TEST(Ecs, ViewsOverOneTwoThreeComponents) {
  Registry r;
  for (int i = 0; i < 100; ++i) {
    Entity e = r.create();
    r.emplace<Position>(e, double(i));
    if (i % 2 == 0) r.emplace<Velocity>(e, 1.0);
    if (i % 5 == 0) r.emplace<Mass>(e, 2.0);
  }
  int n1 = 0, n2 = 0, n3 = 0;
  r.view<Position>().each([&](Position&) { ++n1; });
  r.view<Position, Velocity>().each([&](Entity e, Position& p, Velocity& v) {
    EXPECT_EQ(int(p.x) % 2, 0);
    EXPECT_TRUE(r.has<Velocity>(e));
    p.x += v.dx;
    ++n2;
  });
  r.view<Mass, Velocity, Position>().each([&](Mass&, Velocity&, Position&) { ++n3; });
  EXPECT_EQ(n1, 100);
  EXPECT_EQ(n2, 50);
  EXPECT_EQ(n3, 10);  // multiples of 10
  // The smallest pool leads.
  EXPECT_EQ((r.view<Position, Mass>().size_hint()), 20u);
  int ranged = 0;
  for (Entity e : r.view<Velocity, Mass>()) {
    EXPECT_TRUE((r.has<Velocity, Mass>(e)));
    ++ranged;
  }
  EXPECT_EQ(ranged, 10);
  Registry empty;
  empty.view<Position, Velocity>().each([](Position&, Velocity&) { FAIL(); });
}

TEST(Ecs, RemovingOrDestroyingTheVisitedEntityDuringIterationIsSafe) {
  Registry r;
  std::vector<Entity> es;
  for (int i = 0; i < 50; ++i) {
    es.push_back(r.create());
    r.emplace<Position>(es.back(), double(i));
    r.emplace<Velocity>(es.back(), double(i));
  }
  std::vector<int> seen;
  r.view<Position, Velocity>().each([&](Entity e, Position& p, Velocity&) {
    seen.push_back(int(p.x));
    if (int(p.x) % 2 == 0) r.remove<Velocity>(e);
    if (int(p.x) % 7 == 0) r.destroy(e);
  });
  std::sort(seen.begin(), seen.end());
  ASSERT_EQ(seen.size(), 50u);  // each visited exactly once
  for (int i = 0; i < 50; ++i) EXPECT_EQ(seen[i], i);
  EXPECT_EQ(r.count<Velocity>(), 25u - 4u);  // odd multiples of 7: 7, 21, 35, 49
  // Range-for with removal of the current entity.
  int visited = 0;
  for (Entity e : r.view<Position>()) {
    r.remove<Position>(e);
    ++visited;
  }
  EXPECT_EQ(visited, 50 - 8);  // 0, 7, ..., 49 were destroyed
  EXPECT_EQ(r.count<Position>(), 0u);
}

TEST(Ecs, Resources) {
  Registry r;
  EXPECT_EQ(r.try_resource<Position>(), nullptr);
  std::string message = error_of([&] { r.resource<Position>(); });
  EXPECT_NE(message.find("missing resource"), std::string::npos) << message;
  EXPECT_NE(message.find("Position"), std::string::npos) << message;
  r.insert_resource(Position{1.0});
  EXPECT_EQ(r.resource<Position>().x, 1.0);
  r.resource<Position>().x = 2.0;
  EXPECT_EQ(r.try_resource<Position>()->x, 2.0);
  r.insert_resource(Position{3.0});  // replaces
  EXPECT_EQ(r.resource<Position>().x, 3.0);
  EXPECT_TRUE(r.remove_resource<Position>());
  EXPECT_FALSE(r.has_resource<Position>());
}

// -------------------------------------------------------------------------------------- Hooks

TEST(Hooks, ConstructAndDestroyHooksSeeTheComponent) {
  Registry r;
  std::vector<std::string> log;
  r.on_construct<Position>([&](Registry& reg, Entity e, Position& p) {
    EXPECT_TRUE(reg.has<Position>(e));
    log.push_back("+" + std::to_string(int(p.x)));
  });
  r.on_destroy<Position>([&](Registry& reg, Entity e, Position& p) {
    EXPECT_FALSE(reg.has<Position>(e));  // already gone from the pool
    log.push_back("-" + std::to_string(int(p.x)));
  });
  r.on_destroy<Velocity>(
      [&](Registry&, Entity, Velocity& v) { log.push_back("-v" + std::to_string(int(v.dx))); });
  Entity a = r.create();
  r.emplace<Position>(a, 1.0);
  r.emplace<Velocity>(a, 9.0);
  Entity b = r.create();
  r.emplace<Position>(b, 2.0);
  r.remove<Position>(b);
  r.destroy(a);  // runs the destroy hooks of all its components
  std::vector<std::string> expected{"+1", "+2", "-2", "-1", "-v9"};
  EXPECT_EQ(log, expected);
}

namespace {
struct Partner {
  Entity other;
};
}  // namespace

TEST(Hooks, DestroyHookMayRemoveTheCounterpartOnAnotherEntity) {
  Registry r;
  int calls = 0;
  // A symmetric pair: removing one side removes the other, whose own hook then finds nothing.
  r.on_destroy<Partner>([&](Registry& reg, Entity, Partner& p) {
    ++calls;
    reg.remove<Partner>(p.other);
  });
  Entity a = r.create(), b = r.create(), c = r.create(), d = r.create();
  r.emplace<Partner>(a, b);
  r.emplace<Partner>(b, a);
  r.emplace<Partner>(c, d);
  r.emplace<Partner>(d, c);
  r.destroy(a);
  EXPECT_FALSE(r.has<Partner>(b));
  EXPECT_TRUE(r.alive(b));
  EXPECT_EQ(calls, 2);
  r.remove<Partner>(d);
  EXPECT_FALSE(r.has<Partner>(c));
  EXPECT_EQ(calls, 4);
}

TEST(Hooks, ConstructHookMayAddOtherComponentsButNotToADyingEntity) {
  Registry r;
  r.on_construct<Position>(
      [](Registry& reg, Entity e, Position&) { reg.emplace<Velocity>(e, 7.0); });
  Entity e = r.create();
  r.emplace<Position>(e, 1.0);
  EXPECT_EQ(r.get<Velocity>(e).dx, 7.0);
  r.on_destroy<Mass>([](Registry& reg, Entity e2, Mass&) { reg.emplace<Tag>(e2); });
  r.emplace<Mass>(e, 1.0);
  EXPECT_THROW(r.destroy(e), Error);  // the hook tried to add to the entity being destroyed
  EXPECT_FALSE(r.alive(e));           // destroyed anyway, nothing left behind
  EXPECT_EQ(r.count<Position>() + r.count<Velocity>() + r.count<Mass>() + r.count<Tag>(), 0u);
}

// ---------------------------------------------------------------------------------- Relations

namespace {
struct RendersToTag {};
using RendersTo = Relation<RendersToTag>;
using RenderedBy = InverseRelation<RendersToTag>;
}  // namespace

TEST(Relations, InverseIsMaintainedBothWays) {
  Registry r;
  register_relation<ChildOfTag>(r);
  register_relation<ChildOfTag>(r);  // idempotent
  Entity parent = r.create();
  Entity a = r.create(), b = r.create(), c = r.create();
  r.emplace<ChildOf>(a, parent);
  r.emplace<ChildOf>(b, parent);
  r.emplace<ChildOf>(c, parent);
  ASSERT_TRUE(r.has<Children>(parent));
  EXPECT_EQ(r.get<Children>(parent).sources, (std::vector<Entity>{a, b, c}));
  // Removing a source's relation updates the inverse; the last one removes it.
  r.remove<ChildOf>(b);
  EXPECT_EQ(r.get<Children>(parent).sources, (std::vector<Entity>{a, c}));
  r.destroy(a);  // destroying a source
  EXPECT_EQ(r.get<Children>(parent).sources, (std::vector<Entity>{c}));
  r.remove<ChildOf>(c);
  EXPECT_FALSE(r.has<Children>(parent));
  // Re-targeting is remove + emplace.
  Entity other = r.create();
  r.emplace<ChildOf>(b, parent);
  r.emplace_or_replace(b, ChildOf{other});
  EXPECT_FALSE(r.has<Children>(parent));
  EXPECT_EQ(r.get<Children>(other).sources, (std::vector<Entity>{b}));
}

TEST(Relations, DestroyingTheTargetOrItsInverseRemovesTheSourcesRelations) {
  Registry r;
  register_relation<ChildOfTag>(r);
  Entity parent = r.create();
  std::vector<Entity> kids;
  for (int i = 0; i < 100; ++i) {  // many sources to one target
    kids.push_back(r.create());
    r.emplace<ChildOf>(kids.back(), parent);
  }
  EXPECT_EQ(r.get<Children>(parent).sources.size(), 100u);
  r.destroy(parent);
  for (Entity k : kids) {
    EXPECT_TRUE(r.alive(k));
    EXPECT_FALSE(r.has<ChildOf>(k));
  }
  EXPECT_EQ(r.count<ChildOf>(), 0u);
  EXPECT_EQ(r.count<Children>(), 0u);
  // Removing the inverse component does the same.
  Entity p2 = r.create();
  r.emplace<ChildOf>(kids[0], p2);
  r.emplace<ChildOf>(kids[1], p2);
  r.remove<Children>(p2);
  EXPECT_FALSE(r.has<ChildOf>(kids[0]));
  EXPECT_FALSE(r.has<ChildOf>(kids[1]));
  // A relation to a dead entity is refused and not left behind.
  EXPECT_THROW(r.emplace<ChildOf>(kids[2], parent), Error);
  EXPECT_FALSE(r.has<ChildOf>(kids[2]));
}

TEST(Relations, SeveralKindsOnOneEntityAreIndependent) {
  Registry r;
  register_relation<ChildOfTag>(r);
  register_relation<RendersToTag>(r);
  Entity e = r.create(), parent = r.create(), target = r.create(), child = r.create();
  r.emplace<ChildOf>(e, parent);
  r.emplace<RendersTo>(e, target);
  r.emplace<ChildOf>(child, e);     // e is a source and a target at once
  r.emplace<RendersTo>(target, e);  // a cycle of one kind
  EXPECT_EQ(r.get<Children>(parent).sources, (std::vector<Entity>{e}));
  EXPECT_EQ(r.get<RenderedBy>(target).sources, (std::vector<Entity>{e}));
  EXPECT_EQ(r.get<Children>(e).sources, (std::vector<Entity>{child}));
  r.remove<RendersTo>(e);
  EXPECT_FALSE(r.has<RenderedBy>(target));
  EXPECT_TRUE(r.has<ChildOf>(e));
  r.destroy(e);  // both roles go at once
  EXPECT_FALSE(r.has<Children>(parent));
  EXPECT_FALSE(r.has<ChildOf>(child));
  EXPECT_FALSE(r.has<RendersTo>(target));
  // A self relation.
  Entity self = r.create();
  r.emplace<ChildOf>(self, self);
  r.destroy(self);
  EXPECT_EQ(r.count<ChildOf>(), 0u);
  EXPECT_EQ(r.count<Children>(), 0u);
}

// ------------------------------------------------------------------------ Render-world sync

TEST(SyncToRender, TwinExistsByExtractAndGoesWithItsSource) {
  Engine engine;
  Registry& main = engine.main();
  Registry& render = engine.render();
  Entity e = main.create();
  main.emplace<SyncTo<RenderWorldTag>>(e);
  EXPECT_FALSE(main.has<RenderEntity>(e));  // queued, not yet created
  bool checked = false;
  engine.add_system(MainStage::Extract, [&](Registry& m) {
    if (checked) return;
    ASSERT_TRUE(m.has<RenderEntity>(e));
    Entity twin = m.get<RenderEntity>(e).entity;
    Registry& rw = *m.resource<RenderWorldRef>();
    ASSERT_TRUE(rw.alive(twin));
    EXPECT_EQ(rw.get<MainEntity>(twin).entity, e);
    checked = true;
  });
  engine.update();
  EXPECT_TRUE(checked);
  EXPECT_FALSE(main.has_resource<RenderWorldRef>());  // only during Extract
  Entity twin = main.get<RenderEntity>(e).entity;
  EXPECT_EQ(render.size(), 1u);

  main.destroy(e);
  engine.update();
  EXPECT_FALSE(render.alive(twin));
  EXPECT_EQ(render.size(), 0u);

  // Removing SyncTo also ends the twin; adding it again makes a new one.
  Entity f = main.create();
  main.emplace<SyncTo<RenderWorldTag>>(f);
  engine.update();
  Entity twin_f = main.get<RenderEntity>(f).entity;
  main.remove<SyncTo<RenderWorldTag>>(f);
  EXPECT_FALSE(main.has<RenderEntity>(f));
  engine.update();
  EXPECT_FALSE(render.alive(twin_f));
  main.emplace<SyncTo<RenderWorldTag>>(f);
  engine.update();
  EXPECT_TRUE(render.alive(main.get<RenderEntity>(f).entity));
  // Created and destroyed between two syncs: no twin at all.
  Entity g = main.create();
  main.emplace<SyncTo<RenderWorldTag>>(g);
  main.destroy(g);
  engine.update();
  EXPECT_EQ(render.size(), 1u);
}

// ----------------------------------------------------------------------------------- Stages

TEST(Stages, SystemsRunInStageThenRegistrationOrderInBothWorlds) {
  for (bool pipelined : {false, true}) {
    Engine engine;
    engine.set_pipelined(pipelined);
    std::vector<std::string> log;  // the render thread writes only while main waits (sync point)
    auto add = [&](auto stage, std::string name) {
      engine.add_system(
          stage, [&log, name](Registry&) { log.push_back(name); }, name);
    };
    // Registered out of stage order on purpose.
    add(RenderStage::PostDraw, "PostDraw");
    add(MainStage::Update, "Update1");
    add(RenderStage::Draw, "Draw");
    add(RenderStage::Prepare, "Prepare");
    add(MainStage::Extract, "Extract");
    add(MainStage::Input, "Input");
    add(RenderStage::Queue, "Queue");
    add(MainStage::PostUpdate, "PostUpdate");
    add(RenderStage::PreDraw, "PreDraw");
    add(MainStage::PreUpdate, "PreUpdate");
    add(MainStage::Update, "Update2");
    engine.update();
    engine.wait_for_render();
    std::vector<std::string> expected{"Input",      "PreUpdate", "Update1", "Update2",
                                      "PostUpdate", "Extract",   "Prepare", "Queue",
                                      "PreDraw",    "Draw",      "PostDraw"};
    EXPECT_EQ(log, expected) << (pipelined ? "pipelined" : "single thread");
  }
}

// ---------------------------------------------------------------------------------- Plugins

namespace {
struct PluginLog {
  std::vector<std::string> lines;
};
struct PluginA {
  static constexpr std::string_view name = "PluginA";
  PluginLog* log;
  void build(Engine&) { log->lines.push_back("build A"); }
  void require(Engine&) { log->lines.push_back("require A"); }
  void finish(Engine&) { log->lines.push_back("finish A"); }
};
struct PluginB {
  static constexpr std::string_view name = "PluginB";
  PluginLog* log;
  void build(Engine&) { log->lines.push_back("build B"); }
  void require(Engine& engine) {
    log->lines.push_back("require B");
    engine.require_plugin<PluginA>(name);
  }
  void finish(Engine& engine) {
    // finish() runs after every build(): it may use what later plugins provide.
    log->lines.push_back(engine.main().has_resource<Position>() ? "finish B sees C" : "finish B");
  }
};
struct PluginC {  // no name: the type name is used; declares a dependency instead of require()
  static constexpr std::array<std::string_view, 1> dependencies{"PluginA"};
  PluginLog* log;
  void build(Engine& engine) {
    log->lines.push_back("build C");
    engine.main().insert_resource(Position{1.0});
  }
};
struct FakeTime {  // replaces TimePlugin under its name
  static constexpr std::string_view name = "TimePlugin";
  void build(Engine&) {}
};
struct NeedsTime {
  static constexpr std::string_view name = "NeedsTime";
  static constexpr std::array<std::string_view, 1> dependencies{"TimePlugin"};
  void build(Engine&) {}
};
}  // namespace

static_assert(Plugin<TimePlugin>);
static_assert(Plugin<PluginC>);
static_assert(!Plugin<int>);
static_assert(!Plugin<Position>);

TEST(Plugins, BuildThenRequireThenFinishInOrder) {
  PluginLog log;
  Engine engine;
  engine.add_plugins(PluginGroup{PluginB{&log}, PluginA{&log}}).add_plugin(PluginC{&log});
  EXPECT_TRUE(engine.has_plugin<PluginA>());
  EXPECT_TRUE(engine.has_plugin("PluginB"));
  EXPECT_FALSE(engine.has_plugin<TimePlugin>());
  EXPECT_EQ(engine.get_plugin<PluginA>()->log, &log);
  engine.build();
  std::vector<std::string> expected{"build B",   "build A",         "build C", "require B",
                                    "require A", "finish B sees C", "finish A"};
  EXPECT_EQ(log.lines, expected);
  auto infos = engine.plugins();
  ASSERT_EQ(infos.size(), 3u);
  EXPECT_NE(infos[2].name.find("PluginC"), std::string::npos);
  EXPECT_EQ(infos[2].dependencies, (std::vector<std::string>{"PluginA"}));
  EXPECT_THROW(engine.add_plugin(FakeTime{}), Error);  // too late
}

TEST(Plugins, AddedTwiceFails) {
  PluginLog log;
  Engine engine;
  engine.add_plugin(PluginA{&log});
  std::string message = error_of([&] { engine.add_plugin(PluginA{&log}); });
  EXPECT_NE(message.find("PluginA was added twice"), std::string::npos) << message;
  engine.add_plugin(FakeTime{});
  message = error_of([&] { engine.add_plugin(TimePlugin{}); });  // same name, other type
  EXPECT_NE(message.find("TimePlugin was added twice"), std::string::npos) << message;
}

TEST(Plugins, MissingRequirementNamesBothPlugins) {
  PluginLog log;
  {
    Engine engine;
    engine.add_plugin(PluginB{&log});
    std::string message = error_of([&] { engine.build(); });
    EXPECT_EQ(message, "plugin PluginB requires plugin PluginA, which was not added");
  }
  {
    Engine engine;
    engine.add_plugin(NeedsTime{});
    std::string message = error_of([&] { engine.update(); });
    EXPECT_EQ(message, "plugin NeedsTime requires plugin TimePlugin, which was not added");
  }
  {
    Engine engine;  // a replacement under the same name satisfies the dependency
    engine.add_plugins(NeedsTime{}, FakeTime{});
    EXPECT_NO_THROW(engine.build());
  }
}

TEST(Plugins, DotGraphHasSolidAndDashedEdges) {
  PluginLog log;
  Engine engine;
  engine.add_plugins(default_plugins());
  engine.add_plugins(PluginA{&log}, PluginC{&log});
  std::string dot = plugins_dot(engine.plugins());
  EXPECT_NE(dot.find("digraph plugins"), std::string::npos);
  EXPECT_NE(dot.find("\"CameraPlugin\" -> \"TransformPlugin\" [style=dashed];"), std::string::npos)
      << dot;
  EXPECT_NE(dot.find("PluginC\" -> \"PluginA\";"), std::string::npos) << dot;
}

// ------------------------------------------------------------------------ Built-in plugins

TEST(BuiltinPlugins, TransformsPropagateAlongChildOf) {
  Engine engine;
  engine.add_plugins(TimePlugin{}, TransformPlugin{});
  Registry& m = engine.main();
  Entity root = m.create(), child = m.create(), grandchild = m.create();
  // Geospatial magnitudes: stays exact in double.
  m.emplace<Transform>(root, glm::dvec3(4.0e6, 0, 0),
                       glm::angleAxis(glm::radians(90.0), glm::dvec3(0, 1, 0)));
  m.emplace<Transform>(child, glm::dvec3(1, 0, 0));
  m.emplace<ChildOf>(child, root);
  m.emplace<Transform>(grandchild, glm::dvec3(0, 0, 0), glm::dquat(1, 0, 0, 0), glm::dvec3(2.0));
  m.emplace<ChildOf>(grandchild, child);
  engine.update();
  EXPECT_EQ(m.resource<Time>().frame, 0u);
  glm::dvec3 c = m.get<GlobalTransform>(child).translation();
  EXPECT_NEAR(c.x, 4.0e6, 1e-9);  // +X rotated 90 degrees about Y is -Z
  EXPECT_NEAR(c.z, -1.0, 1e-9);
  EXPECT_NEAR(m.get<GlobalTransform>(grandchild).translation().z, -1.0, 1e-9);
  EXPECT_NEAR(m.get<GlobalTransform>(grandchild).matrix[1][1], 2.0, 1e-12);
  m.remove<ChildOf>(child);  // now a root
  engine.update();
  EXPECT_EQ(m.resource<Time>().frame, 1u);
  EXPECT_NEAR(m.get<GlobalTransform>(child).translation().x, 1.0, 1e-12);
  EXPECT_NEAR(m.get<GlobalTransform>(grandchild).translation().x, 1.0, 1e-12);
}

TEST(BuiltinPlugins, CameraIsExtractedWithPositionAndRotationApart) {
  Engine engine;
  engine.add_plugins(TransformPlugin{}, CameraPlugin{});
  Registry& m = engine.main();
  Entity cam = m.create();
  Camera camera;
  camera.look_at({4.0e6, 100, 0}, {4.0e6 + 10, 100, 0});
  m.emplace<Camera>(cam, camera);
  EXPECT_TRUE(m.has<SyncTo<RenderWorldTag>>(cam));  // cameras are always synced
  Entity object = m.create();
  m.emplace<Transform>(object, glm::dvec3(4.0e6 + 5, 101, 0));
  m.emplace<SyncTo<RenderWorldTag>>(object);
  engine.update();
  Registry& r = engine.render();
  const auto& extracted = r.get<ExtractedCamera>(m.get<RenderEntity>(cam).entity);
  EXPECT_EQ(extracted.position, camera.position);
  EXPECT_NEAR(glm::dot(extracted.rotation, camera.orientation), 1.0, 1e-12);
  EXPECT_EQ(extracted.view_rotation, camera.view_rotation());
  const auto& model = r.get<ExtractedTransform>(m.get<RenderEntity>(object).entity).matrix;
  glm::mat4 relative = camera_relative_model(model, extracted.position);
  EXPECT_FLOAT_EQ(relative[3].x, 5.0f);
  EXPECT_FLOAT_EQ(relative[3].y, 1.0f);
  // With a Transform on the camera entity, the pose comes from its GlobalTransform.
  m.emplace<Transform>(cam, glm::dvec3(1, 2, 3));
  engine.update();
  EXPECT_EQ(r.get<ExtractedCamera>(m.get<RenderEntity>(cam).entity).position, glm::dvec3(1, 2, 3));
}

// ------------------------------------------------------------------------------- Pipelining

TEST(Pipelining, MainFrameNPlus1RunsWhileRenderFrameNDraws) {
  Engine engine;
  engine.add_plugin(PipelinedRenderingPlugin{});
  std::binary_semaphore draw_started{0}, release_draw{0};
  std::atomic<bool> draw0_done{false}, draw0_released{false};
  bool update1_saw_draw_running = false;
  int main_frame = 0, render_frame = 0;  // each touched by one thread only
  engine.add_system(MainStage::Update, [&](Registry&) {
    if (main_frame == 1) {
      // Frame 0's Draw has begun and has not finished while frame 1 updates: the overlap.
      update1_saw_draw_running = draw_started.try_acquire_for(10s) && !draw0_done;
      release_draw.release();
    }
    ++main_frame;
  });
  engine.add_system(RenderStage::Draw, [&](Registry&) {
    if (render_frame == 0) {
      draw_started.release();
      draw0_released = release_draw.try_acquire_for(10s);  // a timeout, so failure cannot hang
      draw0_done = true;
    }
    ++render_frame;
  });
  engine.update();
  engine.update();
  engine.wait_for_render();
  EXPECT_TRUE(update1_saw_draw_running);
  EXPECT_TRUE(draw0_released);
  EXPECT_EQ(render_frame, 2);
}

namespace {
struct Value {
  double v = 0;
};
struct ExtractedValue {
  double v = 0;
};
struct Observed {
  std::vector<std::string> frames;  // what the render world saw, one line per frame
};

// A deterministic simulation whose render-side observations must not depend on threading.
std::vector<std::string> simulate(bool pipelined, int frames) {
  Engine engine;
  TimePlugin time;
  time.fixed_delta = 0.25;
  engine.add_plugin(time);
  if (pipelined) engine.add_plugin(PipelinedRenderingPlugin{});
  engine.render().insert_resource(Observed{});
  engine.add_system(MainStage::Input, [](Registry& m) {
    uint64_t frame = m.resource<Time>().frame;
    if (frame % 3 == 0) {
      Entity e = m.create();
      m.emplace<Value>(e, double(frame));
      m.emplace<SyncTo<RenderWorldTag>>(e);
    }
  });
  engine.add_system(MainStage::Update, [](Registry& m) {
    double t = m.resource<Time>().elapsed_seconds;
    m.view<Value>().each([&](Entity e, Value& value) {
      value.v = value.v * 1.5 + t;
      if (value.v > 200) m.destroy(e);
    });
  });
  engine.add_system(MainStage::Extract, [](Registry& m) {
    Registry& r = *m.resource<RenderWorldRef>();
    m.view<Value, RenderEntity>().each([&](const Value& value, const RenderEntity& twin) {
      r.insert_or_assign(twin.entity, ExtractedValue{value.v});
    });
  });
  engine.add_system(RenderStage::Queue, [](Registry& r) {
    std::vector<std::pair<uint32_t, double>> values;
    r.view<ExtractedValue, MainEntity>().each([&](const ExtractedValue& x, const MainEntity& m) {
      values.emplace_back(m.entity.index, x.v);
    });
    std::sort(values.begin(), values.end());
    std::string line = fmt::format("frame {} t {}:", r.resource<RenderTime>().frame,
                                   r.resource<RenderTime>().elapsed_seconds);
    for (auto [index, v] : values) line += fmt::format(" {}={}", index, v);
    r.resource<Observed>().frames.push_back(line);
  });
  for (int i = 0; i < frames; ++i) engine.update();
  engine.wait_for_render();
  return engine.render().resource<Observed>().frames;
}
}  // namespace

TEST(Pipelining, PipelinedAndSingleThreadModesExtractTheSameResults) {
  std::vector<std::string> single = simulate(false, 40);
  std::vector<std::string> pipelined = simulate(true, 40);
  ASSERT_EQ(single.size(), 40u);
  EXPECT_EQ(single, pipelined);
  EXPECT_EQ(single[0], "frame 0 t 0: 0=0");
  EXPECT_NE(single[20].find("frame 20 t 5:"), std::string::npos);
}

TEST(Pipelining, RenderThreadExceptionSurfacesOnTheMainThread) {
  for (bool pipelined : {false, true}) {
    Engine engine;
    engine.set_pipelined(pipelined);
    int render_frame = 0;
    engine.add_system(RenderStage::Draw, [&](Registry&) {
      if (render_frame++ == 1) throw std::runtime_error("device lost in Draw");
    });
    std::string caught;
    try {
      for (int i = 0; i < 5; ++i) engine.update();
      engine.wait_for_render();
    } catch (const std::runtime_error& e) {
      caught = e.what();
    }
    EXPECT_EQ(caught, "device lost in Draw") << (pipelined ? "pipelined" : "single thread");
    EXPECT_NO_THROW(engine.shutdown());  // reported once; shutting down is clean
  }
}

TEST(Pipelining, MainThreadExceptionMidFrameShutsDownWithoutDeadlock) {
  std::atomic<int> drawn{0};
  {
    Engine engine;
    engine.set_pipelined(true);
    int frame = 0;
    engine.add_system(MainStage::Update, [&](Registry&) {
      if (frame++ == 1) throw Error("main failed");
    });
    engine.add_system(RenderStage::Draw, [&](Registry&) {
      std::this_thread::sleep_for(50ms);  // still drawing frame 0 when frame 1 throws
      ++drawn;
    });
    engine.update();
    EXPECT_THROW(engine.update(), Error);
    // The destructor waits for the frame in flight and joins the render thread.
  }
  EXPECT_EQ(drawn, 1);
}

TEST(Pipelining, RunStopsOnAppExit) {
  Engine engine;
  engine.add_plugins(default_plugins());
  int render_frames = 0;
  engine.add_system(MainStage::Update, [](Registry& m) {
    if (m.resource<Time>().frame == 9) m.resource<AppExit>().requested = true;
  });
  engine.add_system(RenderStage::PostDraw, [&](Registry&) { ++render_frames; });
  engine.run();
  EXPECT_EQ(engine.frames(), 10u);
  EXPECT_EQ(render_frames, 10);
  EXPECT_EQ(engine.render().resource<RenderTime>().frame, 9u);
}
