// Barycentric Chebyshev interpolation; see chebyshev_interpolant.hpp.
#include "kernels/math/chebyshev_interpolant.hpp"

#include <cmath>
#include <numbers>
#include <stdexcept>

namespace stampede::kernels {

std::vector<double> ChebyshevInterpolant::nodes(double a, double b, int n) {
  if (!(a < b) || n < 1) throw std::invalid_argument("ChebyshevInterpolant: needs a < b and at least one node");
  std::vector<double> x(static_cast<std::size_t>(n));
  for (int j = 0; j < n; ++j)
    x[static_cast<std::size_t>(j)] = 0.5 * (a + b) + 0.5 * (b - a) * std::cos((2 * j + 1) * std::numbers::pi / (2 * n));
  return x;
}

ChebyshevInterpolant::ChebyshevInterpolant(double a, double b, std::vector<double> values)
    : nodes_(nodes(a, b, static_cast<int>(values.size()))), values_(std::move(values)) {
  const int n = static_cast<int>(values_.size());
  weights_.resize(values_.size());
  // The barycentric weights of first-kind points: (-1)^j sin((2j + 1) pi / 2n), up to a common factor.
  for (int j = 0; j < n; ++j)
    weights_[static_cast<std::size_t>(j)] = (j % 2 ? -1.0 : 1.0) * std::sin((2 * j + 1) * std::numbers::pi / (2 * n));
}

double ChebyshevInterpolant::operator()(double x) const {
  double num = 0, den = 0;
  for (std::size_t j = 0; j < nodes_.size(); ++j) {
    const double d = x - nodes_[j];
    if (d == 0.0) return values_[j];
    const double t = weights_[j] / d;
    num += t * values_[j];
    den += t;
  }
  return num / den;
}

}  // namespace stampede::kernels
