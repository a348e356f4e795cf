// The unnormalised sinc; see sinc.hpp.
#include "kernels/math/sinc.hpp"

#include <cmath>

namespace stampede::kernels {

double sinc(double x) { return std::abs(x) < 1e-8 ? 1.0 : std::sin(x) / x; }

}  // namespace stampede::kernels
