// What metacalibration adds to an output row: the shear response R and the four sheared fits.
#pragma once

#include <array>
#include <cmath>

namespace stampede {

struct MetacalRecord {
  // R_ij = (e_i(+step_j) - e_i(-step_j)) / (2 step): row i the ellipticity component, column j
  // the applied shear's.
  double r11 = NAN, r12 = NAN, r21 = NAN, r22 = NAN;
  // The fits of the sheared images, in the order 1p, 1m, 2p, 2m (kMetacalTypes after noshear):
  // what selection responses for cuts on S/N and size need.
  std::array<double, 4> e1{NAN, NAN, NAN, NAN}, e2{NAN, NAN, NAN, NAN};
  std::array<double, 4> snr{NAN, NAN, NAN, NAN}, radius{NAN, NAN, NAN, NAN};
};

}  // namespace stampede
