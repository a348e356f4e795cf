// The 12-point Gauss-Legendre quadrature rule, exact for polynomials of degree <= 23.
#pragma once

#include <array>

namespace stampede::kernels {

// Nodes x[i] and weights w[i] on [-1, 1], x from near +1 down to near -1, found by Newton
// iteration on P_12 to double precision (the weights sum to 2 within a few ulp).
struct GaussLegendre12 {
  static constexpr int kN = 12;
  std::array<double, kN> x{}, w{};

  // Integral of f over [a, b]: sum_i w_i f(mid + half x_i) half, i = 0 .. 11 in order.
  template <class F>
  double integrate(double a, double b, F&& f) const {
    const double mid = 0.5 * (a + b), half = 0.5 * (b - a);
    double s = 0;
    for (int i = 0; i < kN; ++i) s += w[i] * f(mid + half * x[i]);
    return s * half;
  }
};

// The rule, computed once on first use (thread-safe static initialisation, immutable after).
const GaussLegendre12& gauss_legendre_12();

}  // namespace stampede::kernels
