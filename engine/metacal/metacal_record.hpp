// What metacalibration adds to an output row: the shear response R and the four sheared fits.
#pragma once

#include <array>
#include <cmath>

#include "engine/fit/fit_result.hpp"

namespace stampede {

struct MetacalRecord {
  // R_ij = (e_i(+step_j) - e_i(-step_j)) / (2 step): row i the ellipticity component, column j
  // the applied shear's.
  double r11 = NAN, r12 = NAN, r21 = NAN, r22 = NAN;
  // The fits of the sheared images, in the order 1p, 1m, 2p, 2m (kMetacalTypes after noshear):
  // what selection responses for cuts on S/N and size need.
  std::array<double, 4> e1{NAN, NAN, NAN, NAN}, e2{NAN, NAN, NAN, NAN};
  std::array<double, 4> snr{NAN, NAN, NAN, NAN}, radius{NAN, NAN, NAN, NAN};

  // Sheared image k's measurement (k = 0..3: 1p, 1m, 2p, 2m), whichever estimator made it.
  void set_sheared(int k, const FitResult& r) {
    const auto i = static_cast<std::size_t>(k);
    e1[i] = r.params[index(Param::kE1)];
    e2[i] = r.params[index(Param::kE2)];
    snr[i] = r.snr;
    radius[i] = r.params[index(Param::kRadius)];
  }
  // R from the sheared measurements recorded, for applied shears of +-step.
  void set_response(double step) {
    const double two_step = 2 * step;
    r11 = (e1[0] - e1[1]) / two_step;
    r21 = (e2[0] - e2[1]) / two_step;
    r12 = (e1[2] - e1[3]) / two_step;
    r22 = (e2[2] - e2[3]) / two_step;
  }
};

}  // namespace stampede
