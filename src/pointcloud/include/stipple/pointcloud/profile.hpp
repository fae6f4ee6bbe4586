#pragma once
// Height profiles: the points whose horizontal distance to a polyline is at most half a width
// (the corridor), as a cross-section image (distance along the line against height, in the
// renderer's colour modes), a CSV with one row a point, and a LAS/LAZ file. No point cap: the
// inputs are streamed and the corridor's points spill to a temporary file beside the output.
// `stipple profile` and the viewer's profile export run this; the viewer's profile window draws
// the corridor of the loaded points with the same rasterizer.
#include <atomic>
#include <cstdint>
#include <filesystem>
#include <optional>
#include <vector>

#include <glm/vec2.hpp>
#include <glm/vec3.hpp>

#include "stipple/pointcloud/filters.hpp"
#include "stipple/pointcloud/point_cloud.hpp"
#include "stipple/renderer/gpu.hpp"

namespace stipple::pc {

// A polyline in the source's X/Y with a width: the corridor.
struct ProfileLine {
  std::vector<glm::dvec2> vertices;  // at least two
  double width = 1.0;
  double length() const;
  // The distance along the line of the nearest point of the polyline to `p`, and the horizontal
  // distance to it (signed: positive left of the line's direction); nullopt when farther than
  // width / 2. The first segment wins ties.
  struct Hit {
    double along, offset;
  };
  std::optional<Hit> locate(const glm::dvec2& p) const;
};
ProfileLine parse_profile_line(const std::string& text, double width);

// One corridor point for the image: position in the profile plane, and what colours it.
struct ProfileSample {
  float along;   // distance along the line
  float height;  // z minus ProfileRaster's z origin
  float offset;  // signed distance from the line (nearer the viewer: smaller)
  uint32_t rgba;
  uint32_t attributes;  // PointChunk::Vertex's packing
};

struct ProfileImageOptions {
  uint32_t width = 1600, height = 600;
  ColorMode color = ColorMode::Auto;
  glm::vec3 background{0.07f, 0.08f, 0.1f};
  int point_radius = 1;  // pixels around each point's own (0: one pixel)
};

// Draws samples into an image: distance along the line to the right, height up, each axis
// scaled to fill the image (the scales are reported), with grid lines at round steps.
struct ProfileFrame {
  double length = 0;             // of the line
  glm::dvec2 z_range{0.0, 1.0};  // heights drawn bottom to top
  double z_origin = 0;           // ProfileSample::height is z - z_origin
  glm::dvec2 grid_step{1.0, 1.0};
  double pixels_per_unit_x = 1, pixels_per_unit_z = 1;
  // Pixel (x right, y down) of a profile position, and back.
  glm::dvec2 to_pixel(double along, double z, const glm::uvec2& size) const;
  glm::dvec2 from_pixel(const glm::dvec2& pixel, const glm::uvec2& size) const;
};
ProfileFrame make_profile_frame(double length, glm::dvec2 z_range, double z_origin,
                                const glm::uvec2& size);
// `attributes` of the shaded cloud decides Auto (RGB when it has colours).
gpu::Image draw_profile(const std::vector<ProfileSample>& samples, const ProfileFrame& frame,
                        const ProfileImageOptions& options, const CloudAttributes& attributes);

struct ProfileJob {
  std::vector<std::filesystem::path> inputs;
  ProfileLine line;
  PointFilter filter;
  ClipRegion region;
  std::optional<glm::dvec3> enu_origin;  // lon/lat inputs: line and region in local ENU metres
  std::filesystem::path png, csv, las;   // any may be empty
  ProfileImageOptions image;
  bool progress = true;
  std::atomic<uint64_t>* points_done = nullptr;
};

struct ProfileResult {
  uint64_t points_read = 0, points_in_corridor = 0;
  double length = 0;
  glm::dvec2 z_range{0.0, 0.0};
  ProfileFrame frame;
};

// Throws stipple::Error naming the file and the problem; no output is left behind then.
ProfileResult run_profile(const ProfileJob& job);

// The corridor of points already in memory (the viewer's cloud: world space is the source frame
// turned Y up, lon/lat sources in local ENU metres), filtered as the renderer filters them.
std::vector<ProfileSample> profile_samples(const PointCloud& cloud, const ProfileLine& line,
                                           const PointFilter& filter, const ClipRegion& region,
                                           double z_origin);

// The CLI's and the CSV's column names, in order.
const char* profile_csv_header();

}  // namespace stipple::pc
