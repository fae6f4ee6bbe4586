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

#include "math/aabb.hpp"
#include "math/camera.hpp"
#include "pointcloud/point_cloud.hpp"
#include "pointcloud/point_renderer.hpp"
#include "pointcloud/procedural.hpp"

namespace stipple {
class Engine;
}

namespace stipple::app {

struct PointCloudInputs {
  std::vector<std::filesystem::path> files;  // empty: the procedural scene
  pc::SceneParams scene;
  size_t chunk_points = 1 << 20;  // smaller chunks make the point budget finer
  bool progress = true;
};

// Main- and render-world resource (copied in Extract): how points are drawn. Colour modes are
// chosen in the shader, so changing one costs nothing.
struct PointDrawSettings {
  pc::PointRenderSettings render;  // the point pipeline (same flags as `stipple render`)
  uint64_t budget = 0;             // at most this many points (whole chunks, nearest first); 0: all
  bool compute = false;  // the compute rasterizer (seed 001) instead of the point pipeline
  bool hqs = false;      // compute rasterizer: high-quality shading
};

// Main-world component: the loaded points, shared with the render world (never modified; a
// reload makes a new one with a higher generation).
struct PointCloudData {
  std::shared_ptr<const pc::PointCloud> cloud;
  std::vector<Aabb> chunk_bounds;  // world space, per cloud chunk (picking, budget order)
  uint64_t generation = 0;
};

// Main-world resource: what was loaded.
struct SceneInfo {
  Aabb world_bounds;
  uint64_t points = 0;
  pc::CloudAttributes attributes;
  std::string name;  // first file's name, or "procedural scene"
};

// Files (LAS/LAZ/COPC, or one 3D Tiles tileset path or URL) or the procedural scene.
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

}  // namespace stipple::app
