#pragma once
// Summary statistics of measured values (benchmarks, `render --stats`).
#include <vector>

namespace stipple {

// The median: the middle value, or the mean of the two middle ones for an even count; 0 for
// none.
double median(std::vector<double> values);

}  // namespace stipple
