// Unit phasors along an arithmetic progression of angles, for DFT weights and phase ramps.
#pragma once

#include <complex>

namespace stampede::kernels {

// out[j] = exp(i (a + j d)), j < n: by rotation (a multiplication instead of a sincos per term),
// taken afresh from sincos every 8 terms so that the products' rounding stays within a few ulps.
void phasors(double a, double d, int n, std::complex<double>* out);

}  // namespace stampede::kernels
