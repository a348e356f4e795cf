// The 12-point Gauss-Legendre rule; see gauss_legendre.hpp.
#include "kernels/math/gauss_legendre.hpp"

#include <cmath>
#include <numbers>

namespace stampede::kernels {
namespace {

GaussLegendre12 make_rule() {
  constexpr int kN = GaussLegendre12::kN;
  GaussLegendre12 rule;
  for (int i = 0; i < kN; ++i) {
    // Start at the asymptotic estimate of the i-th root; P_12 by its three-term recurrence.
    double z = std::cos(std::numbers::pi * (i + 0.75) / (kN + 0.5));
    double dp = 0;
    for (int it = 0; it < 100; ++it) {
      double p0 = 1, p1 = z;
      for (int k = 2; k <= kN; ++k) {
        const double p2 = ((2 * k - 1) * z * p1 - (k - 1) * p0) / k;
        p0 = p1;
        p1 = p2;
      }
      dp = kN * (z * p1 - p0) / (z * z - 1);
      const double dz = p1 / dp;
      z -= dz;
      if (std::abs(dz) < 1e-16) break;
    }
    rule.x[i] = z;
    rule.w[i] = 2 / ((1 - z * z) * dp * dp);
  }
  return rule;
}

}  // namespace

const GaussLegendre12& gauss_legendre_12() {
  static const GaussLegendre12 rule = make_rule();  // immutable after (thread-safe) initialisation
  return rule;
}

}  // namespace stampede::kernels
