#pragma once
// TransformPlugin: double-precision transforms (seed 000, section 5: all CPU transforms are
// double) and GlobalTransform propagation along ChildOf.
#include <string_view>

#include <glm/gtc/quaternion.hpp>
#include <glm/mat4x4.hpp>
#include <glm/vec3.hpp>

#include "stipple/engine/registry.hpp"
#include "stipple/engine/relation.hpp"

namespace stipple {

class Engine;

// Local transform, relative to the ChildOf parent (or the world for roots).
struct Transform {
  glm::dvec3 translation{0.0};
  glm::dquat rotation{1.0, 0.0, 0.0, 0.0};
  glm::dvec3 scale{1.0};
  glm::dmat4 matrix() const;
};

// World transform, computed in PostUpdate; added automatically with Transform.
struct GlobalTransform {
  glm::dmat4 matrix{1.0};
  glm::dvec3 translation() const { return glm::dvec3(matrix[3]); }
};

// Render-world copy of GlobalTransform for entities synced to the render world.
struct ExtractedTransform {
  glm::dmat4 matrix{1.0};
};

// Roots are entities with a Transform and no ChildOf parent that has one; a child without a
// Transform ends its branch. ChildOf cycles (no root) are left untouched.
void propagate_transforms(Registry& main);
void extract_transforms(Registry& main);

struct TransformPlugin {
  static constexpr std::string_view name = "TransformPlugin";
  static constexpr std::string_view description =
      "double-precision Transform, GlobalTransform along ChildOf";
  void build(Engine& engine);
};

}  // namespace stipple
