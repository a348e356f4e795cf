// Weak-lensing shear applied to an ellipticity, in the reduced-shear convention e = (a - b) / (a + b).
#pragma once

#include <complex>

namespace stampede::kernels {

// The observed ellipticity of a source with intrinsic e under reduced shear g (Seitz & Schneider
// 1997): e_obs = (e + g) / (1 + conj(g) e).
std::complex<double> lens_ellipticity(std::complex<double> e, std::complex<double> g);

}  // namespace stampede::kernels
