#include "stipple/engine/transform.hpp"

#include <glm/gtc/matrix_transform.hpp>

#include "stipple/engine/engine.hpp"
#include "stipple/engine/sync.hpp"

namespace stipple {

glm::dmat4 Transform::matrix() const {
  glm::dmat4 m = glm::mat4_cast(rotation);
  m[0] *= scale.x;
  m[1] *= scale.y;
  m[2] *= scale.z;
  m[3] = glm::dvec4(translation, 1.0);
  return m;
}

namespace {

void propagate_children(Registry& r, Entity parent, const glm::dmat4& parent_matrix) {
  const auto* children = r.try_get<Children>(parent);
  if (!children) return;
  // Nothing below adds or removes components, so the list and the pointers stay valid.
  for (Entity child : children->sources) {
    const auto* local = r.try_get<Transform>(child);
    auto* global = r.try_get<GlobalTransform>(child);
    if (!local || !global) continue;
    global->matrix = parent_matrix * local->matrix();
    propagate_children(r, child, global->matrix);
  }
}

}  // namespace

void propagate_transforms(Registry& r) {
  r.view<Transform, GlobalTransform>().each(
      [&](Entity e, const Transform& local, GlobalTransform& global) {
        if (const auto* parent = r.try_get<ChildOf>(e);
            parent && r.has<GlobalTransform>(parent->target))
          return;  // reached from its root
        global.matrix = local.matrix();
        propagate_children(r, e, global.matrix);
      });
}

void extract_transforms(Registry& main) {
  Registry& render = *main.resource<RenderWorldRef>();
  main.view<GlobalTransform, RenderEntity>().each(
      [&](const GlobalTransform& global, const RenderEntity& twin) {
        render.insert_or_assign(twin.entity, ExtractedTransform{global.matrix});
      });
}

void TransformPlugin::build(Engine& engine) {
  Registry& main = engine.main();
  register_relation<ChildOfTag>(main);
  main.on_construct<Transform>([](Registry& r, Entity e, Transform&) {
    if (!r.has<GlobalTransform>(e)) r.emplace<GlobalTransform>(e);
  });
  engine.add_system(MainStage::PostUpdate, propagate_transforms, "propagate_transforms");
  engine.add_system(MainStage::Extract, extract_transforms, "extract_transforms");
}

}  // namespace stipple
