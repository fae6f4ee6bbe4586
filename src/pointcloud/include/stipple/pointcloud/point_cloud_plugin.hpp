#pragma once
// PointCloudPlugin: point clouds as entities. The main world loads the inputs (LAS/LAZ/COPC
// files, or the built-in procedural scene) into one entity with PointCloudData + Transform +
// SyncTo<Render>; Extract hands the (shared, immutable) data and the draw settings to the
// twin; Prepare uploads it; Queue adds the point pass to the frame graph, nearest chunks first
// within the point budget.
#include <array>
#include <cstdint>
#include <filesystem>
#include <memory>
#include <optional>
#include <string_view>
#include <vector>

#include <glm/vec3.hpp>

#include "stipple/io/procedural.hpp"
#include "stipple/math/aabb.hpp"
#include "stipple/math/camera.hpp"
#include "stipple/pointcloud/point_cloud.hpp"
#include "stipple/pointcloud/point_renderer.hpp"
#include "stipple/pointcloud/scene.hpp"

namespace stipple {
class Engine;
class Registry;
}  // namespace stipple

namespace stipple::pc {

struct PointCloudInputs {
  std::vector<std::filesystem::path> files;  // empty: `points`, else the procedural scene
  // Points already in memory (a caller's arrays), drawn instead of files or the scene.
  std::shared_ptr<const pc::PointCloud> points;
  io::SceneParams scene;
  size_t chunk_points = 1 << 20;  // smaller chunks make the point budget finer
  bool progress = true;
  bool keep_extras = false;  // PointChunk::extras, for GPS-time and point-source filters
  // Points in memory may hold none: the frame draws other content (Gaussian splats) over an
  // empty cloud; otherwise an empty input is an error.
  bool allow_empty = false;
};

// Main-world component: the loaded points, shared with the render world (never modified; a
// reload makes a new one with a higher generation).
struct PointCloudData {
  std::shared_ptr<const pc::PointCloud> cloud;
  std::vector<Aabb> chunk_bounds;  // world space, per cloud chunk (picking, budget order)
  uint64_t generation = 0;
  // The built-in scene's parameters when it was generated (its points can be made again, one
  // by one, for inspection); unset for files.
  std::optional<io::SceneParams> scene;
};

// LAS/LAZ/COPC files read whole, a copy of the points in memory, or the procedural scene
// (tilesets: tiles3d::TilesetPlugin).
pc::PointCloud load_inputs(const PointCloudInputs& inputs);
std::vector<Aabb> chunk_bounds(const pc::PointCloud& cloud);

// The chunks to draw under a point budget: nearest (bounding-box distance) first while the
// budget holds, in that order; budget 0 keeps every chunk in its original order. Chunks are
// given by bounds and point counts.
std::vector<uint32_t> select_chunks(const std::vector<Aabb>& bounds,
                                    const std::vector<uint32_t>& counts,
                                    const glm::dvec3& camera_position, uint64_t budget);

// The point nearest to the ray's origin among those within `tan_radius` (the tangent of the
// half-angle of a cone around the ray, e.g. a few pixels' worth). Chunks whose bounds miss the
// cone are skipped.
// Removes every cloud PointCloudPlugin holds, from both worlds at once: called at the sync point
// (MainStage::Extract), where the render world is idle, so that no frame draws it after this
// one (VirtualPointCloudPlugin's background build replaces the sample it drew meanwhile).
void remove_point_clouds(Registry& main, Registry& render);

std::optional<glm::dvec3> pick_point(const PointCloudData& data, const glm::dvec3& origin,
                                     const glm::dvec3& direction, double tan_radius);

struct PointCloudPlugin {
  static constexpr std::string_view name = "PointCloudPlugin";
  static constexpr std::string_view description =
      "loads point clouds into the main world; uploads and draws them (point budget)";
  static constexpr std::array<std::string_view, 3> dependencies{"GpuPlugin", "RenderGraphPlugin",
                                                                "TransformPlugin"};
  static constexpr std::array<std::string_view, 1> optional_dependencies{"CameraPlugin"};
  PointCloudInputs inputs;
  PointDrawSettings settings;
  void build(Engine& engine);
};

}  // namespace stipple::pc
