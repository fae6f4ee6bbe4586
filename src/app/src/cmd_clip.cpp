// `stipple clip`: the points of LAS/LAZ/COPC inputs inside a box or polygon that pass attribute
// filters, written to one LAS/LAZ file (pc::clip_to_las, which the viewer's export runs too).
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <memory>
#include <string>
#include <vector>

#include "stipple/app/commands.hpp"
#include "stipple/app/filter_options.hpp"
#include "stipple/core/error.hpp"
#include "stipple/pointcloud/clip.hpp"

namespace stipple::app {
namespace {

struct ClipArgs {
  std::vector<std::string> inputs;
  std::string output;
  FilterArgs filters;
  bool outside = false;
};

void run_clip(const ClipArgs& args) {
  const auto start = std::chrono::steady_clock::now();
  pc::ClipJob job;
  for (const auto& in : args.inputs) job.inputs.emplace_back(in);
  job.output = args.output;
  job.filter = make_filter(args.filters);
  job.region = make_region(args.filters);
  if (args.outside) job.region.mode = pc::ClipMode::Outside;
  std::string ext = job.output.extension().string();
  for (char& c : ext) c = char(std::tolower(static_cast<unsigned char>(c)));
  if (ext != ".las" && ext != ".laz")
    fail("{}: the output must be a .las or .laz file", job.output.string());
  const pc::ClipResult r = pc::clip_to_las(job);
  const double seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  std::printf("kept %llu of %llu points, wrote %s (LAS 1.4 point format %u%s) in %.2f s\n",
              static_cast<unsigned long long>(r.points_written),
              static_cast<unsigned long long>(r.points_read), job.output.string().c_str(),
              unsigned(r.point_format), ext == ".laz" ? ", LAZ" : "", seconds);
  if (r.files_skipped > 0)
    std::printf("%llu input(s) lie outside the region and were not read\n",
                static_cast<unsigned long long>(r.files_skipped));
  if (r.points_written > 0)
    std::printf("bounds: %.3f,%.3f,%.3f to %.3f,%.3f,%.3f\n", r.min.x, r.min.y, r.min.z, r.max.x,
                r.max.y, r.max.z);
  else
    std::fprintf(stderr, "stipple: warning: no point passed the region and filters\n");
}

}  // namespace

void add_clip_command(CLI::App& cli) {
  auto args = std::make_shared<ClipArgs>();
  auto* cmd = cli.add_subcommand(
      "clip",
      "Write the points of LAS/LAZ/COPC inputs inside a box or polygon, and passing attribute "
      "filters, to one LAS/LAZ file (every record field, VLRs, EVLRs and CRS kept; LAS 1.4)");
  cmd->add_option("inputs", args->inputs, "Input files (.las, .laz, .copc.laz)")
      ->required()
      ->check(CLI::ExistingFile);
  cmd->add_option("-o,--output", args->output, "Output .las or .laz (written atomically)")
      ->required();
  add_filter_options(cmd, args->filters, FilterFlags::Clip);
  cmd->add_flag("--outside", args->outside,
                "Keep the points outside the boxes/polygons instead of those inside");
  cmd->callback([args] { run_clip(*args); });
}

}  // namespace stipple::app
