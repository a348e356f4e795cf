// Polynomial interpolation of a smooth function on [a, b] through its values at Chebyshev points
// (of the first kind), evaluated by the barycentric formula: for a function analytic near the
// interval the error falls geometrically with the number of points, and the evaluation is stable.
#pragma once

#include <vector>

namespace stampede::kernels {

class ChebyshevInterpolant {
 public:
  // The n points on [a, b] at which the values are taken (n >= 1, a < b), in the order the
  // constructor expects them; callers may compute the values in parallel.
  static std::vector<double> nodes(double a, double b, int n);

  ChebyshevInterpolant() = default;
  // values[j] = f(nodes(a, b, values.size())[j]). Throws std::invalid_argument for a >= b or no values.
  ChebyshevInterpolant(double a, double b, std::vector<double> values);

  // The interpolant at x (exact at the nodes; outside [a, b] it extrapolates the polynomial).
  double operator()(double x) const;
  bool empty() const { return values_.empty(); }

 private:
  std::vector<double> nodes_, weights_, values_;
};

}  // namespace stampede::kernels
