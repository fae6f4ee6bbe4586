// `stipple profile`: a height profile along a polyline of LAS/LAZ/COPC inputs: the cross-section
// image, a CSV of every point in the corridor and/or a LAS/LAZ file of them (pc::run_profile,
// which the viewer's profile export runs too). No point cap.
#include <chrono>
#include <cstdio>
#include <memory>
#include <string>
#include <vector>

#include "stipple/app/commands.hpp"
#include "stipple/app/filter_options.hpp"
#include "stipple/core/error.hpp"
#include "stipple/pointcloud/profile.hpp"

namespace stipple::app {
namespace {

struct ProfileArgs {
  std::vector<std::string> inputs;
  std::string line;
  double width = 0;
  std::string png, csv, las;
  uint32_t image_width = 1600, image_height = 600;
  std::string color = "auto";
  int point_radius = 1;
  FilterArgs filters;
};

void run_profile_command(const ProfileArgs& args) {
  const auto start = std::chrono::steady_clock::now();
  pc::ProfileJob job;
  for (const auto& in : args.inputs) job.inputs.emplace_back(in);
  job.line = pc::parse_profile_line(args.line, args.width);
  job.filter = make_filter(args.filters);
  job.region = make_region(args.filters);
  job.png = args.png;
  job.csv = args.csv;
  job.las = args.las;
  job.image.width = args.image_width;
  job.image.height = args.image_height;
  job.image.color = pc::parse_color_mode(args.color);
  job.image.point_radius = args.point_radius;
  if (!job.las.empty()) {
    std::string ext = job.las.extension().string();
    for (char& c : ext) c = char(std::tolower(static_cast<unsigned char>(c)));
    if (ext != ".las" && ext != ".laz")
      fail("{}: --las needs a .las or .laz file name", job.las.string());
  }
  const pc::ProfileResult r = pc::run_profile(job);
  const double seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  std::printf("profile: %llu of %llu points within %g of the line (length %.3f) in %.2f s\n",
              static_cast<unsigned long long>(r.points_in_corridor),
              static_cast<unsigned long long>(r.points_read), job.line.width / 2, r.length,
              seconds);
  if (r.points_in_corridor > 0) std::printf("heights %.3f to %.3f\n", r.z_range.x, r.z_range.y);
  if (!job.png.empty())
    std::printf(
        "%s: %ux%u, distance 0 to %.3f left to right, height %.3f to %.3f bottom to top; grid "
        "every %g along, %g up\n",
        job.png.string().c_str(), job.image.width, job.image.height, r.frame.length,
        r.frame.z_range.x, r.frame.z_range.y, r.frame.grid_step.x, r.frame.grid_step.y);
  if (!job.csv.empty()) std::printf("%s: one row a point\n", job.csv.string().c_str());
  if (!job.las.empty()) std::printf("%s: the corridor's points\n", job.las.string().c_str());
}

}  // namespace

void add_profile_command(CLI::App& cli) {
  auto args = std::make_shared<ProfileArgs>();
  auto* cmd = cli.add_subcommand(
      "profile",
      "Height profile of LAS/LAZ/COPC inputs along a polyline: every point whose horizontal "
      "distance to the line is at most --width / 2, as an image, a CSV and/or a LAS file (no "
      "point cap)");
  cmd->add_option("inputs", args->inputs, "Input files (.las, .laz, .copc.laz)")
      ->required()
      ->check(CLI::ExistingFile);
  cmd->add_option("--line", args->line,
                  "The polyline 'x0,y0,x1,y1[,x2,y2...]' in the source CRS's units")
      ->required();
  cmd->add_option("--width", args->width, "Corridor width (source units), centred on the line")
      ->required();
  cmd->add_option("-o,--output", args->png, "Cross-section PNG (distance along vs height)");
  cmd->add_option("--csv", args->csv,
                  "CSV, one row a point: distance,x,y,z,offset and every attribute");
  cmd->add_option("--las", args->las, "The corridor's points as LAS/LAZ (records kept whole)");
  cmd->add_option("--image-width", args->image_width, "Image width in pixels")
      ->check(CLI::Range(16u, 16384u))
      ->capture_default_str();
  cmd->add_option("--image-height", args->image_height, "Image height in pixels")
      ->check(CLI::Range(16u, 16384u))
      ->capture_default_str();
  cmd->add_option("--color", args->color,
                  "Colour by: auto, rgb, intensity, classification, elevation, return, constant")
      ->check(CLI::IsMember(
          {"auto", "rgb", "intensity", "classification", "elevation", "return", "constant"}))
      ->capture_default_str();
  cmd->add_option("--point-radius", args->point_radius, "Pixels drawn around each point")
      ->check(CLI::Range(0, 16))
      ->capture_default_str();
  add_filter_options(cmd, args->filters, FilterFlags::Clip);
  cmd->callback([args] { run_profile_command(*args); });
}

}  // namespace stipple::app
