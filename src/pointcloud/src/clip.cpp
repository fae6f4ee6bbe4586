#include "stipple/pointcloud/clip.hpp"

#include "selection.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <memory>

#include "stipple/core/error.hpp"
#include "stipple/core/log.hpp"
#include "stipple/core/progress.hpp"
#include "stipple/io/las.hpp"
#include "stipple/math/aabb.hpp"
#include "stipple/math/geo.hpp"

namespace stipple::pc {
namespace {

bool same_extra_bytes(const io::LasHeader& a, const io::LasHeader& b) {
  if (a.extra_bytes_per_point != b.extra_bytes_per_point) return false;
  if (a.extra_bytes.size() != b.extra_bytes.size()) return false;
  for (size_t i = 0; i < a.extra_bytes.size(); ++i) {
    const auto &x = a.extra_bytes[i], &y = b.extra_bytes[i];
    if (x.data_type != y.data_type || x.options != y.options || x.name != y.name) return false;
  }
  return true;
}

bool same_crs(const io::Crs& a, const io::Crs& b) {
  if (a.empty() || b.empty()) return a.empty() == b.empty();
  if (a.epsg != 0 && b.epsg != 0) return a.epsg == b.epsg && a.vertical_epsg == b.vertical_epsg;
  return a.wkt == b.wkt && a.geokeys == b.geokeys;
}

// VLRs that describe the source's encoding or index, not its data: never copied.
bool encoding_record(const io::Vlr& v) {
  if (v.user_id == "laszip encoded") return true;  // LASzip's (22204)
  if (v.user_id == "lascompatible") return true;   // LASzip's LAS 1.4 compatibility mode
  if (v.user_id == "copc") return true;            // COPC info (1) and hierarchy (1000)
  if (v.user_id == "LASF_Spec" && v.record_id == 4) return true;      // Extra Bytes: written anew
  if (v.user_id == "LASF_Spec" && v.record_id == 65535) return true;  // waveform data packets
  return false;
}

}  // namespace

io::LasWriteOptions clip_output_options(const std::vector<io::LasHeader>& headers,
                                        const std::filesystem::path& output) {
  const io::LasHeader& first = headers.front();
  bool same_format = true, same_scale = true;
  bool rgb = false, nir = false, wave = false, gps_adjusted = false, gps_week = false;
  glm::dvec3 scale = first.scale;
  Aabb bounds;
  for (const io::LasHeader& h : headers) {
    same_format &=
        h.point_format == first.point_format && h.point_record_length == first.point_record_length;
    same_scale &= h.scale == first.scale && h.offset == first.offset;
    if (!same_extra_bytes(h, first))
      fail("{} and {} carry different extra bytes: clip them separately", first.path, h.path);
    if (!same_crs(h.crs, first.crs))
      fail("{} ({}) and {} ({}) are in different coordinate systems: clip them separately",
           first.path, first.crs.describe(), h.path, h.crs.describe());
    rgb |= h.has_rgb;
    nir |= h.has_nir;
    wave |= h.has_waveform;
    ((h.global_encoding & 1) ? gps_adjusted : gps_week) = true;
    scale = glm::min(scale, h.scale);
    if (h.point_count > 0) {
      bounds.extend(h.min);
      bounds.extend(h.max);
    }
  }
  if (gps_adjusted && gps_week)
    STIPPLE_WARN("the inputs mix adjusted standard GPS time and GPS week time; {} keeps {}'s flag",
                 output.string(), first.path);
  io::LasWriteOptions o;
  o.version_minor = 4;
  std::string ext = output.extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(), ::tolower);
  o.compress = ext == ".laz";
  if (same_format) {
    o.point_format = first.point_format;
  } else {
    o.point_format = wave ? (rgb || nir ? 10 : 9) : nir ? 8 : rgb ? 7 : 6;
  }
  if (same_scale) {
    o.scale = first.scale;
    o.offset = first.offset;
  } else {
    o.scale = scale;
    o.offset = bounds.empty() ? first.offset : glm::floor(bounds.min);
  }
  o.extra_bytes = first.extra_bytes;
  if (first.extra_bytes.empty() && first.extra_bytes_per_point > 0) {
    // Undocumented extra bytes: described as opaque bytes (type 0) so they keep their place.
    for (uint16_t left = first.extra_bytes_per_point; left > 0;) {
      io::ExtraBytesDescriptor d;
      d.data_type = 0;
      d.options = uint8_t(std::min<uint16_t>(left, 255));
      d.name = "undocumented";
      o.extra_bytes.push_back(d);
      left = uint16_t(left - d.options);
    }
  }
  for (const io::Vlr& v : first.vlrs)
    if (!encoding_record(v)) o.vlrs.push_back(v);
  for (const io::Vlr& v : first.evlrs) {
    if (encoding_record(v)) continue;
    if (v.data.size() != v.data_size) {
      STIPPLE_WARN("{}: EVLR {} {} ({} bytes) is too large to copy; {} leaves it out", first.path,
                   v.user_id, v.record_id, v.data_size, output.string());
      continue;
    }
    o.evlrs.push_back(v);
  }
  o.global_encoding = first.global_encoding;
  o.file_source_id = first.file_source_id;
  o.guid = first.guid;
  o.system_identifier = first.system_identifier.empty() ? "stipple" : first.system_identifier;
  o.generating_software = "stipple clip";
  return o;
}

namespace {}  // namespace

namespace {

detail::StreamOptions stream_options(const ClipJob& job) {
  detail::StreamOptions o;
  o.inputs = job.inputs;
  o.filter = job.filter;
  o.region = job.region;
  o.enu_origin = job.enu_origin;
  o.progress = job.progress;
  o.points_done = job.points_done;
  o.batch_points = job.batch_points;
  return o;
}

}  // namespace

ClipResult clip_to_las(const ClipJob& job) {
  const detail::StreamOptions stream = stream_options(job);
  const std::vector<io::LasHeader> headers = detail::read_headers(stream);
  std::error_code ec;
  for (const auto& in : job.inputs)
    if (std::filesystem::equivalent(in, job.output, ec))
      fail("{}: the output would overwrite the input {}", job.output.string(), in.string());
  const io::LasWriteOptions options = clip_output_options(headers, job.output);
  ClipResult result;
  result.point_format = options.point_format;
  glm::dvec3 lo(std::numeric_limits<double>::infinity()), hi(-lo);
  // The writer checks the output's folder before any input is read.
  io::LasWriter writer(job.output, options);
  detail::StreamCounts counts;
  detail::stream_inputs(
      stream, headers, counts,
      [&](const io::PointBatch& batch, const detail::Selection&, const io::LasHeader&) {
        for (const glm::dvec3& p : batch.positions) {
          lo = glm::min(lo, p);
          hi = glm::max(hi, p);
        }
        writer.write(batch);
      });
  writer.close();
  result.points_read = counts.points_read;
  result.files_skipped = counts.files_skipped;
  result.points_written = writer.points_written();
  if (result.points_written > 0) {
    result.min = lo;
    result.max = hi;
  }
  return result;
}

uint64_t count_kept_points(const ClipJob& job) {
  const detail::StreamOptions stream = stream_options(job);
  const std::vector<io::LasHeader> headers = detail::read_headers(stream);
  detail::StreamCounts counts;
  uint64_t kept = 0;
  detail::stream_inputs(stream, headers, counts,
                        [&](const io::PointBatch& batch, const detail::Selection&,
                            const io::LasHeader&) { kept += batch.size(); });
  return kept;
}

}  // namespace stipple::pc
