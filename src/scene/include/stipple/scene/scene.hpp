#pragma once
// The one place that picks the scene plugin for `stipple render`, `stipple view` and
// stipple.render (Python): one 3D Tiles tileset (a tileset.json path or an http(s) URL) is
// streamed by tiles3d::TilesetPlugin; LAS/LAZ/COPC files, points in memory, or no input at all
// (the built-in scene), are read by pc::PointCloudPlugin. Both give the same main-world contract
// (pc::SceneInfo, pc::PointDrawSettings), so what follows in either works over both.
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "stipple/math/camera.hpp"
#include "stipple/pointcloud/point_cloud.hpp"
#include "stipple/pointcloud/point_renderer.hpp"
#include "stipple/renderer/gpu.hpp"
#include "stipple/scene/filter_args.hpp"

namespace stipple {
class Engine;
class Registry;
}  // namespace stipple

namespace stipple::scene {

enum class Renderer { Auto, Billboard, Compute };

struct SceneOptions {
  std::vector<std::string> inputs;  // empty: the built-in scene (or `points`)
  // Points already in memory (points_from_columns), drawn instead of files or the built-in
  // scene when set; `inputs` must then be empty.
  std::shared_ptr<const pc::PointCloud> points;
  pc::PointRenderSettings render;
  Renderer renderer = Renderer::Auto;  // resolve_renderer picks one
  bool hqs = false;                    // compute renderer: high-quality shading
  uint64_t budget = 0;                 // point clouds: at most this many points (nearest chunks)
  size_t chunk_points = 1 << 20;       // point clouds: chunk size (finer chunks, finer budget)
  uint64_t scene_points = 1'000'000;
  uint32_t seed = 1;
  // Tilesets and COPC: refine while a tile's screen-space error exceeds this; 0: the source's
  // default (max_sse_for).
  double max_sse = 0;
  uint64_t memory_mb = 512;  // tilesets: resident tile memory budget
  // Point clouds larger than the in-memory path's budget (or with --virtual) are drawn from a
  // pointlet cache (pc::VirtualPointCloudPlugin, seed 002).
  bool force_virtual = false;
  int fill_radius = -1;          // compute: hole filling radius; -1: 1 when virtualized, else 0
  float occlusion_beta = 0.0f;   // compute: occlusion check threshold (radians); 0: off
  uint64_t bucket = 25'000'000;  // B
  uint64_t pointlets = 100'000;  // m
  std::string cache_dir;         // empty: beside the input
  std::string host_memory;       // empty: a quarter of RAM
  std::string gpu_memory;        // virtualized: device memory budget; empty: what B needs
  // --classes, --returns, --clip-box ...: apply_filters() moves them into `render`.
  FilterArgs filters;
  // Point clouds: keep the per-point extras (GPS time, point source) so that filters on them
  // can be turned on later (the viewer); render keeps them only when its filters need them.
  bool keep_extras = false;
};

// Reads the clip polygons and puts the filters and clip region into options.render; throws
// stipple::Error for a bad polygon file.
void apply_filters(SceneOptions& options);

// The default view of the loaded scene, seen from `azimuth`/`elevation` (degrees, Z-up) so that
// the data fills most of a width x height image (ViewFit): fitted to the points of point
// clouds, in memory or in a pointlet cache (the virtualized path), else to a tileset's volume
// (TilesetStream::world_bounds; render refits to the tiles' points once they are in), else to
// the scene's bounds.
Camera frame_scene(Registry& main, uint32_t width, uint32_t height, double azimuth = 30.0,
                   double elevation = 40.0, double fov = 50.0);

// Whether `options` take the virtualized path (for point-cloud inputs), and why.
bool use_virtual_path(const SceneOptions& options, std::string* reason = nullptr);

// The renderer for `options` on this device: an explicit --renderer; the compute rasterizer
// for the virtualized path and (auto) for 10 million points or more, on any adapter: there
// billboards cost far more a frame (100M on the H200: 1336 ms against 4.4 ms; 12M on lavapipe:
// 6953 ms against 134 ms) and 1-pixel points close the surface; billboards otherwise (point
// sizes above one pixel), which `render` still swaps for compute where the data's density gives
// 1-pixel points. A 3D Tiles tileset counts as the points its memory budget (--memory-mb) holds,
// since its size is not known up front (the tiled 1B points on the H200: 0.18 against 31.5 GPU
// ms a frame). `reason` says why, for the summary line.
Renderer resolve_renderer(const SceneOptions& options, const gpu::Context& ctx,
                          std::string* reason = nullptr);
const char* renderer_name(Renderer renderer);

// Whether `inputs` name one tileset or COPC file (streamed) rather than point-cloud files.
bool is_tileset_scene(const SceneOptions& options);
// --max-sse, or the source's default: 16 px for 3D Tiles, 2 px for COPC, whose node error is
// its point spacing (so a level is refined while its spacing covers more than 2 pixels).
double max_sse_for(const SceneOptions& options);

// The camera of `render` and `view`: from --camera 'eye,target' (source coordinates, Z up),
// else frame_scene's for a width x height image from the azimuth and elevation (degrees); fov
// in degrees.
Camera scene_camera(Registry& main, const std::string& camera, uint32_t width, uint32_t height,
                    double azimuth, double elevation, double fov);

// Adds the scene plugin for `options` to `engine`; throws stipple::Error for what the chosen
// path cannot do.
void add_scene_plugin(Engine& engine, const SceneOptions& options);

// "1,2,3" -> {1, 2, 3}; throws stipple::Error naming `what` unless exactly `expected` finite
// numbers.
std::vector<double> parse_numbers(const std::string& text, size_t expected, const char* what);

}  // namespace stipple::scene
