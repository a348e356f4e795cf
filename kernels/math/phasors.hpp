// Unit phasors along an arithmetic progression of angles, for DFT weights and phase ramps.
#pragma once

#include <complex>

namespace stampede::kernels {

// out[j] = exp(i (a + j d)), j < n: by rotation, taken afresh from sincos every 8 terms so that the
// products' rounding stays within a few ulps (a sincos per term was the bulk of the transforms
// that use it).
void phasors(double a, double d, int n, std::complex<double>* out);

}  // namespace stampede::kernels
