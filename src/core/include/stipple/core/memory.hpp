#pragma once
// The process's resident memory, for budgets that cover the whole process (the virtualized
// renderer keeps its loaded points within what the rest of the process leaves).
#include <cstdint>

namespace stipple {

// Bytes resident now (Linux: /proc/self/statm); 0 where unknown.
uint64_t resident_bytes();
// The peak so far (getrusage); 0 where unknown.
uint64_t peak_resident_bytes();

}  // namespace stipple
