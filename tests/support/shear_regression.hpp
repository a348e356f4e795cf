// Least squares y = (1 + m) x + c, for shear tests: measured against applied (or true) shears.
#pragma once

#include <vector>

namespace stampede::testing {

inline void regress(const std::vector<double>& x, const std::vector<double>& y, double* m, double* c) {
  double sx = 0, sy = 0, sxx = 0, sxy = 0;
  const double n = static_cast<double>(x.size());
  for (std::size_t i = 0; i < x.size(); ++i) sx += x[i], sy += y[i], sxx += x[i] * x[i], sxy += x[i] * y[i];
  const double slope = (n * sxy - sx * sy) / (n * sxx - sx * sx);
  *m = slope - 1;
  *c = (sy - slope * sx) / n;
}

}  // namespace stampede::testing
