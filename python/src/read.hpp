#pragma once
// Points of a LAS/LAZ/COPC file as packed records for a numpy structured array (stipple.read).
#include <cstddef>
#include <cstdint>
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include "stipple/io/las.hpp"

namespace stipple::python {

struct FieldSpec {
  std::string name;    // laspy's name
  std::string format;  // numpy type string, e.g. "<u2", "(3,)<f8"
  size_t size = 0;     // bytes in the record
  // Writes the field of every point of a batch: `base` is the field in the first record.
  std::function<void(const io::PointBatch&, uint8_t* base, size_t stride)> fill;
  size_t offset = 0;  // in the record, set by read_points
};

// Every field of the file's point format, extra bytes included, in laspy's order.
std::vector<FieldSpec> point_fields(const io::LasHeader& header);

struct ReadResult {
  std::vector<FieldSpec> fields;
  size_t itemsize = 0;
  uint64_t points = 0;
  std::vector<uint8_t> data;  // points * itemsize
};

// Reads every point of `path`, keeping `fields` (all when empty). Throws stipple::Error naming
// the file for an unknown field, an unreadable file or one with fewer points than declared.
ReadResult read_points(const std::string& path,
                       const std::optional<std::vector<std::string>>& fields,
                       const std::function<void()>& before_read = {});

}  // namespace stipple::python
