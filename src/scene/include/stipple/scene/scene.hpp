#pragma once
// The one scene assembly of every front end: `stipple render` and Python (render_image),
// `stipple view`, the bench commands and the web page. The inputs are classified once
// (classify_scene: what they are, how many points their headers declare, whether point files take
// the virtualized path) and that SceneSource is handed down; plan_scene resolves the renderer for
// the device; add_scene_plugin adds the plugin that reads or streams it: one 3D Tiles tileset,
// COPC, Potree or EPT source (path or http(s) URL) streamed by tiles3d::TilesetPlugin; LAS/LAZ
// files, points in memory or the built-in scene read by pc::PointCloudPlugin; LAS/LAZ files over
// the host budget drawn from a pointlet cache by pc::VirtualPointCloudPlugin (seed 002). All give
// the same main-world contract (pc::SceneInfo, pc::PointDrawSettings), so what follows in either
// works over all. place_camera frames the data and sizes the points; settle_streamed_scene
// refits a streamed source's view once its first tiles are in. A front end keeps only what is
// its own: its target (PNG, window, the page's canvas) and its event loop.
#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "stipple/io/source.hpp"
#include "stipple/io/splats.hpp"
#include "stipple/math/camera.hpp"
#include "stipple/pointcloud/point_cloud.hpp"
#include "stipple/pointcloud/point_renderer.hpp"
#include "stipple/renderer/gpu.hpp"
#include "stipple/scene/filter_args.hpp"
#include "stipple/splats/splats.hpp"

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
  Renderer renderer = Renderer::Auto;  // plan_scene resolves it
  bool hqs = false;                    // compute renderer: high-quality shading
  uint64_t budget = 0;                 // point clouds: at most this many points (nearest chunks)
  size_t chunk_points = 1 << 20;       // point clouds: chunk size (finer chunks, finer budget)
  uint64_t scene_points = 1'000'000;
  uint32_t seed = 1;
  // Streamed sources: refine while a tile's screen-space error exceeds this; 0: the source's
  // default (max_sse_for).
  double max_sse = 0;
  uint64_t memory_mb = 512;   // streamed sources: resident tile memory budget
  uint64_t splat_budget = 0;  // a streamed splat tileset: at most this many splats drawn (0: any)
  // Splats: quads or tiles; empty: the device's faster one (splats::default_splat_rasterizer).
  std::optional<splats::SplatRasterizer> splat_rasterizer;
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
  // --sun-time: the date and time whose sun lights the sky (render.sky), at the data's location
  // (scene_lon_lat); solar::parse_sun_time says how it reads. plan_scene turns it into the sun's
  // azimuth and elevation. Empty: render.sky's own azimuth and elevation.
  std::string sun_time;
  // Point clouds: keep the per-point extras (GPS time, point source) so that filters on them
  // can be turned on later (the viewer); render keeps them only when its filters need them.
  bool keep_extras = false;
  // The viewer's first image at once: virtualized LAS/LAZ whose pointlet cache has to be built
  // are drawn from about this many points read across the inputs (pc::read_las_sample) while
  // the cache builds in the background, then from the cache (VirtualCloudOptions::
  // build_in_background). 0: the cache is built first. A current cache is opened as without it.
  uint64_t progressive_points = 0;
  // Virtualized: the selection runs on its own thread and frames draw the last one meanwhile
  // (VirtualCloudOptions::async_selection): the viewer and bench virtual; render makes each
  // selection in its frame.
  bool async_selection = false;
};

// What the scene's inputs are, found once.
enum class SourceKind : uint8_t {
  BuiltIn,     // no input: the procedural scene
  Memory,      // points in memory (SceneOptions::points)
  PointFiles,  // LAS/LAZ files read whole, in memory or through the pointlet cache
  Streamed,    // one hierarchical source (`format`: 3D Tiles, COPC, Potree or EPT)
};

struct SceneSource {
  SourceKind kind = SourceKind::BuiltIn;
  io::SourceFormat format = io::SourceFormat::Las;  // Streamed: which hierarchy
  // Points known up front: the LAS headers, a COPC header, the built-in scene's or the memory's
  // count; 0 where streaming alone tells (3D Tiles, Potree, EPT).
  uint64_t points = 0;
  uint64_t host_budget = 0;  // --host-memory, else a quarter of RAM
  bool virtualized = false;  // PointFiles drawn from a pointlet cache (--virtual, or too large)
  std::string virtual_reason;
  bool streamed() const { return kind == SourceKind::Streamed; }
};

// Classifies `options.inputs` (each once: io::source_format), reads the point files' headers
// once and decides the virtualized path. Throws stipple::Error naming the input for what cannot
// be read or mixed (a streamed source with other inputs, points in memory with files).
SceneSource classify_scene(const SceneOptions& options);

// The scene as it will be drawn: the options with the filters applied (apply_filters), the
// renderer resolved for the device and blending's form on the compute rasterizer (HQS) chosen,
// the source as classified.
struct ScenePlan {
  SceneOptions options;
  SceneSource source;
  std::string renderer_reason;  // for the summary line
  bool renderer_auto = false;   // the renderer was chosen here (--renderer auto)
  // The compute rasterizer draws it (resolved, or the virtualized path, which draws with it).
  bool compute() const { return options.renderer == Renderer::Compute || source.virtualized; }
  // Gaussian splat files among the inputs (io::is_splat_path), read whole by plan_scene and
  // taken out of options.inputs: splats::SplatPlugin draws them in the points' frame, depth-
  // tested against the points; splats alone draw over an empty cloud. Their coordinates are
  // the world's as the files store them (no CRS).
  std::vector<std::shared_ptr<const io::SplatSet>> splats;
  // A splat tileset among the inputs (io::is_splat_tileset_path), taken out of options.inputs
  // too: streamed with the view (tiles3d::SplatTilesetPlugin, --max-sse, --memory-mb and
  // --splat-budget), its drawn tiles' splats one set for splats::SplatPlugin. At most one.
  std::string splat_tileset;
  uint64_t splat_count() const;
};

// Splats the streamed splat tileset drew in the latest frame (0 without one).
uint64_t drawn_splats(Registry& main);

// The longitude, latitude and height (degrees, WGS 84) of the centre of the scene's data, from
// its CRS through PROJ (io::LonLatTransform): the first point file's header, a COPC header, an
// EPT's WKT, the built-in scene's UTM zone, or the centre of a geocentric 3D Tiles root volume.
// nullopt (and `why` says so) where the data has no CRS or is not geo-referenced.
std::optional<glm::dvec3> scene_lon_lat(const SceneOptions& options, const SceneSource& source,
                                        std::string* why = nullptr);

// For options.sun_time: the sun's azimuth and elevation at the scene's location
// (scene_lon_lat) into options.render.sky. Throws stipple::Error when the location is unknown
// (then --sun AZ,EL is needed). Logs where and when.
void resolve_sun(SceneOptions& options, const SceneSource& source);

// A survey's tiles as one cloud: each input that is a folder becomes its .las/.laz files (in
// name order; pointlet caches and their temporaries beside them are passed over), other inputs
// stay as they are. Throws stipple::Error naming the folder when it holds no LAS/LAZ file, or
// a file that is not one.
std::vector<std::string> expand_input_folders(const std::vector<std::string>& inputs);

// expand_input_folders + classify_scene + apply_filters + resolve_renderer for `ctx` (and
// resolve_sun).
ScenePlan plan_scene(const SceneOptions& options, const gpu::Context& ctx);

// Reads the clip polygons and puts the filters and clip region into options.render; throws
// stipple::Error for a bad polygon file.
void apply_filters(SceneOptions& options);

// The renderer for the scene on this device: an explicit --renderer; the compute rasterizer
// for the virtualized path and (auto) for 10 million points or more, on any adapter: there
// billboards cost far more a frame (100M on the H200: 1336 ms against 4.4 ms; 12M on lavapipe:
// 6953 ms against 134 ms) and 1-pixel points close the surface; billboards otherwise (point
// sizes above one pixel), which place_camera still swaps for compute where the data's density
// gives 1-pixel points. A 3D Tiles tileset counts as the points its memory budget (--memory-mb)
// holds, since its size is not known up front (the tiled 1B points on the H200: 0.18 against
// 31.5 GPU ms a frame). `reason` says why, for the summary line.
Renderer resolve_renderer(const SceneOptions& options, const SceneSource& source,
                          const gpu::Context& ctx, std::string* reason = nullptr);
const char* renderer_name(Renderer renderer);

// --max-sse, or the source's default: 16 px for 3D Tiles, 2 px for COPC, Potree and EPT, whose
// node error is their point spacing (so a level is refined while its spacing covers more than 2
// pixels).
double max_sse_for(const SceneOptions& options, const SceneSource& source);

// What every front end draws with: the engine's core plugins, the device (the compute
// rasterizer's features requested, so that the renderer can be chosen once the adapter is known)
// and the frame graph.
struct EngineCore {
  std::string backend;         // "dawn", "wgpu"; empty: $STIPPLE_BACKEND, else wgpu
  bool pipelined = false;      // the render world on its own thread (PipelinedRenderingPlugin)
  bool keep_history = false;   // per-pass GPU times of every frame (RenderStats::history)
  std::string dump_graph;      // write the frame graph as Graphviz DOT
  uint32_t history_limit = 0;  // keep_history: of the last this many frames only (0: all)
  // Each frame waits for the GPU to finish it (RenderGraphPlugin::wait_for_gpu): off in the web
  // page, where each wait is a round trip through the browser's GPU process.
  bool wait_for_gpu = true;
  uint32_t max_frames_in_flight = 0;  // RenderGraphPlugin's (without wait_for_gpu)
};
void add_engine_core(Engine& engine, const EngineCore& core);

// Adds the scene plugin for `plan` to `engine`; throws stipple::Error for what the chosen path
// cannot do.
void add_scene_plugin(Engine& engine, const ScenePlan& plan);

// Where the camera looks from and at.
struct SceneView {
  uint32_t width = 1280, height = 720;
  // 'eye_x,eye_y,eye_z,target_x,target_y,target_z' in the data's coordinates (Z up); empty:
  // framed from azimuth and elevation (degrees) so that the data fills the image.
  std::string camera;
  double azimuth = 30.0, elevation = 40.0, fov = 50.0;
};

// Places the scene's camera (view.camera, else frame_scene's) and sizes the points from the
// data's density at it where no --point-size was given (streamed sources: 2 px until they are
// streamed, see settle_streamed_scene). With `one_pixel_compute` (render and the page, not the
// interactive window, whose camera moves closer), an auto renderer that got billboards draws
// with the compute rasterizer where the points come out at one pixel: the same image (blending
// as HQS does), far faster (lavapipe, 12M points: 134 ms against 6953 ms a frame); `plan` then
// says so. Returns the camera.
Camera place_camera(Engine& engine, ScenePlan& plan, const SceneView& view, bool one_pixel_compute);

// The default view of the loaded scene, seen from `azimuth`/`elevation` (degrees, Z-up) so that
// the data fills most of a width x height image (ViewFit): fitted to the points of point
// clouds, in memory or in a pointlet cache (the virtualized path), else to a tileset's volume
// (TilesetStream::world_bounds; settle_streamed_scene refits to the tiles' points once they are
// in), else to the scene's bounds.
Camera frame_scene(Registry& main, uint32_t width, uint32_t height, double azimuth = 30.0,
                   double elevation = 40.0, double fov = 50.0);

// The camera from --camera 'eye,target' (source coordinates, Z up), else frame_scene's for a
// width x height image from the azimuth and elevation (degrees); fov in degrees.
Camera scene_camera(Registry& main, const std::string& camera, uint32_t width, uint32_t height,
                    double azimuth, double elevation, double fov);

// A streamed source's progress towards the image (a main-world resource that
// settle_streamed_scene keeps): the front end waits (`loading`), then draws `settled` more
// frames before it keeps the image or reports it done.
struct StreamSettle {
  bool loading = true;   // tiles the view selects are still streaming (and max_frames not met)
  bool capped = false;   // max_frames reached
  uint64_t settled = 0;  // frames run since the source was streamed for the final view
};

// For streamed sources (render and the page): frames run while tiles stream in; once the first
// tiles are drawn the camera is refitted to their points (unless view.camera was given) and
// streamed again; once idle (or at `max_frames`), the point size is fitted to what is drawn
// (unless --point-size), the budget's effect is warned about, and a view whose tiles hold no
// points at all is an error naming the source. Adds the system that keeps StreamSettle.
void settle_streamed_scene(Engine& engine, const ScenePlan& plan, const SceneView& view,
                           uint64_t max_frames);

// "1,2,3" -> {1, 2, 3}; throws stipple::Error naming `what` unless exactly `expected` finite
// numbers.
std::vector<double> parse_numbers(const std::string& text, size_t expected, const char* what);

}  // namespace stipple::scene
