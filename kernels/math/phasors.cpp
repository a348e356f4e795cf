// Unit phasors; see phasors.hpp.
#include "kernels/math/phasors.hpp"

namespace stampede::kernels {

void phasors(double a, double d, int n, std::complex<double>* out) {
  constexpr int kExact = 8;
  const std::complex<double> step = std::polar(1.0, d);
  for (int j = 0; j < n; ++j) out[j] = j % kExact == 0 ? std::polar(1.0, a + j * d) : out[j - 1] * step;
}

}  // namespace stampede::kernels
