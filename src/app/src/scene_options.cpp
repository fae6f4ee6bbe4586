// The flags of the scene that `render` and `view` share.
#include "stipple/app/scene.hpp"

namespace stipple::app {

void add_scene_options(CLI::App* cmd, SceneOptions& options) {
  cmd->add_option_function<std::string>(
         "--renderer",
         [&options](const std::string& v) {
           options.renderer = v == "compute"     ? Renderer::Compute
                              : v == "billboard" ? Renderer::Billboard
                                                 : Renderer::Auto;
         },
         "auto (compute on a GPU from 10M points, else billboard; the summary says which), "
         "billboard (the point pipeline) or compute (compute rasterizer, 1-pixel points)")
      ->check(CLI::IsMember({"auto", "billboard", "compute"}))
      ->default_str("auto");
  cmd->add_flag("--hqs", options.hqs,
                "Compute renderer: high-quality shading (average points within 1% of the "
                "nearest depth)");
  cmd->add_option("--max-sse", options.max_sse,
                  "Tilesets and COPC: refine tiles while their screen-space error exceeds this "
                  "(pixels; default 16 for 3D Tiles, 2 for COPC, whose error is the point spacing)")
      ->check(CLI::PositiveNumber);
  cmd->add_option("--fill-radius", options.fill_radius,
                  "Compute renderer: fill empty pixels from drawn ones within this radius (seed "
                  "002 III-D; default 1 on the virtualized path, else 0)")
      ->check(CLI::Range(0, 8));
  cmd->add_option("--occlusion-beta", options.occlusion_beta,
                  "Compute renderer: drop points a nearer neighbour sees at an angle of at most "
                  "this (radians; eq. 4 of seed 002, which uses 0.1); 0: off")
      ->check(CLI::Range(0.0f, 1.5f))
      ->capture_default_str();
  cmd->add_flag("--virtual", options.force_virtual,
                "Point clouds: draw from a pointlet cache in bounded memory (seed 002; chosen "
                "automatically for inputs larger than the host budget)");
  cmd->add_option("--bucket", options.bucket,
                  "Virtualized: the point bucket B, the most points drawn in a frame")
      ->check(CLI::Range(uint64_t(1), uint64_t(1) << 31))
      ->capture_default_str();
  cmd->add_option("--pointlets", options.pointlets,
                  "Virtualized: m of k = 2^floor(log2(n / m)), about how many pointlets")
      ->check(CLI::Range(uint64_t(1), uint64_t(1) << 31))
      ->capture_default_str();
  cmd->add_option("--cache", options.cache_dir,
                  "Virtualized: folder of the pointlet cache (default: beside the input, else "
                  "~/.cache/stipple)");
  cmd->add_option("--host-memory", options.host_memory,
                  "Host memory budget, e.g. 4G (default: a quarter of RAM): larger inputs take the "
                  "virtualized path, which keeps the whole process under it (on a CPU adapter the "
                  "device's buffers too, and the bucket is lowered to fit); a budget under what "
                  "the process needs for itself is an error naming the least that works");
  cmd->add_option("--gpu-memory", options.gpu_memory,
                  "Virtualized: device memory for the points, e.g. 2G (default: what the bucket "
                  "needs, 32 bytes a point); a bucket that does not fit is lowered");
  cmd->add_option("--budget", options.budget,
                  "Point budget: draw at most this many points (0: all); point clouds: nearest "
                  "chunks first; tilesets and COPC: coarser tiles where the view wants more")
      ->capture_default_str();
  cmd->add_option("--memory-mb", options.memory_mb,
                  "Tilesets: resident tile memory budget in MiB (least recently used evicted)")
      ->check(CLI::Range(uint64_t(1), uint64_t(1) << 20))
      ->capture_default_str();
  cmd->add_option("--splat-budget", options.splat_budget,
                  "Splat tilesets: draw at most this many splats (0: no limit); coarser tiles "
                  "where the view wants more")
      ->capture_default_str();
  cmd->add_option_function<std::string>(
         "--splat-rasterizer",
         [&options](const std::string& v) {
           options.splat_rasterizer =
               v == "auto"
                   ? std::nullopt
                   : std::optional<splats::SplatRasterizer>(splats::parse_splat_rasterizer(v));
         },
         "Gaussian splats: auto (tiles on a GPU, quads on a CPU adapter: the faster there), "
         "quads (sorted instanced quads, fixed-function blending) or tiles (16x16 tiles in "
         "compute, f32 blending)")
      ->check(CLI::IsMember({"auto", "quads", "tiles"}))
      ->default_str("auto");
  auto* sun_time = cmd->add_option_function<std::string>(
      "--sun-time",
      [&options](const std::string& v) {
        options.sun_time = v;
        options.render.sky.enabled = true;
      },
      "The sky's sun at this date and time at the data's location (from its CRS), e.g. "
      "2026-06-21T06:00: local mean solar time at the data's longitude, or with Z or +HH:MM "
      "civil time at that offset from UTC; implies --sky. Data without a CRS need --sun");
  if (CLI::Option* sun = cmd->get_option_no_throw("--sun")) sun_time->excludes(sun);
  add_filter_options(cmd, options.filters, FilterFlags::Render);
}

}  // namespace stipple::app
