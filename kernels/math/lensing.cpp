// Shear applied to an ellipticity; see lensing.hpp.
#include "kernels/math/lensing.hpp"

namespace stampede::kernels {

std::complex<double> lens_ellipticity(std::complex<double> e, std::complex<double> g) {
  return (e + g) / (1.0 + std::conj(g) * e);
}

}  // namespace stampede::kernels
