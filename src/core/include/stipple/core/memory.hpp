#pragma once
// The process's resident memory, for budgets that cover the whole process (the virtualized
// renderer keeps its loaded points within what the rest of the process leaves), and the sizes
// users give those budgets in (--memory, --host-memory, --gpu-memory).
#include <cstdint>
#include <string>

namespace stipple {

// Bytes resident now (Linux: /proc/self/statm); 0 where unknown.
uint64_t resident_bytes();
// The peak so far (getrusage); 0 where unknown.
uint64_t peak_resident_bytes();

// "2G", "512M", "64k", "1000000" -> bytes. Throws stipple::Error on anything else.
uint64_t parse_size(const std::string& text);

}  // namespace stipple
