#include "stipple/engine/camera.hpp"

#include "stipple/engine/engine.hpp"
#include "stipple/engine/sync.hpp"
#include "stipple/engine/transform.hpp"

namespace stipple {

const ExtractedCamera* first_extracted_camera(Registry& render) {
  const ExtractedCamera* first = nullptr;
  render.view<ExtractedCamera>().each([&](const ExtractedCamera& c) {
    if (!first) first = &c;
  });
  return first;
}

Camera to_camera(const ExtractedCamera& c) {
  Camera camera;
  camera.position = c.position;
  camera.orientation = c.rotation;
  camera.fov_y = c.fov_y;
  camera.near_plane = c.near_plane;
  return camera;
}

glm::mat4 camera_relative_model(const glm::dmat4& model, const glm::dvec3& camera_position) {
  glm::dmat4 relative = model;
  relative[3] = glm::dvec4(glm::dvec3(model[3]) - camera_position, 1.0);
  return glm::mat4(relative);
}

void extract_cameras(Registry& main) {
  Registry& render = *main.resource<RenderWorldRef>();
  main.view<Camera, RenderEntity>().each(
      [&](Entity e, const Camera& camera, const RenderEntity& twin) {
        Camera pose = camera;
        if (const auto* global = main.try_get<GlobalTransform>(e)) {
          const glm::dmat4& m = global->matrix;
          pose.position = glm::dvec3(m[3]);
          glm::dmat3 rotation(glm::normalize(glm::dvec3(m[0])), glm::normalize(glm::dvec3(m[1])),
                              glm::normalize(glm::dvec3(m[2])));
          pose.orientation = glm::quat_cast(rotation);
        }
        render.insert_or_assign(
            twin.entity, ExtractedCamera{pose.position, pose.orientation, pose.view_rotation(),
                                         pose.fov_y, pose.near_plane});
      });
}

void CameraPlugin::build(Engine& engine) {
  // A camera is always drawn from the render world, so it always gets a twin.
  engine.main().on_construct<Camera>([](Registry& r, Entity e, Camera&) {
    if (!r.has<SyncTo<RenderWorldTag>>(e)) r.emplace<SyncTo<RenderWorldTag>>(e);
  });
  engine.add_system(MainStage::Extract, extract_cameras, "extract_cameras");
}

}  // namespace stipple
