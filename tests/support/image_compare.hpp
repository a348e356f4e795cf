// Image comparison for the renderer and kernel tests: the worst pixel difference over the
// reference's peak, the measure the GalSim comparisons and the ISA-vs-scalar tests are stated in.
#pragma once

#include <algorithm>
#include <cmath>
#include <limits>
#include <vector>

namespace stampede::testing {

// max |a - b| / max |b|; 0 when both are zero everywhere, infinite when only b is.
inline double worst_over_peak(const std::vector<double>& a, const std::vector<double>& b) {
  double peak = 0, worst = 0;
  for (std::size_t i = 0; i < a.size(); ++i) {
    peak = std::max(peak, std::abs(b[i]));
    worst = std::max(worst, std::abs(a[i] - b[i]));
  }
  if (peak > 0) return worst / peak;
  return worst > 0 ? std::numeric_limits<double>::infinity() : 0.0;
}

}  // namespace stampede::testing
