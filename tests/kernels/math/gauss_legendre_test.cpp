// Tests kernels/math/gauss_legendre: the 12-point rule's nodes and weights, and exactness for
// polynomials of degree <= 23 (and not 24).
#include "kernels/math/gauss_legendre.hpp"

#include <gtest/gtest.h>

#include <cmath>

namespace stampede::kernels {
namespace {

TEST(GaussLegendre12, NodesAreSymmetricAndOrderedAndWeightsSumToTwo) {
  const GaussLegendre12& r = gauss_legendre_12();
  double sum = 0;
  for (int i = 0; i < GaussLegendre12::kN; ++i) {
    sum += r.w[i];
    EXPECT_GT(r.w[i], 0);
    if (i > 0) {
      EXPECT_LT(r.x[i], r.x[i - 1]);
    }
    EXPECT_NEAR(r.x[i], -r.x[GaussLegendre12::kN - 1 - i], 1e-15);
    EXPECT_NEAR(r.w[i], r.w[GaussLegendre12::kN - 1 - i], 1e-15);
  }
  EXPECT_NEAR(sum, 2.0, 4e-16);
  // Largest node of P_12 (Abramowitz & Stegun table 25.4).
  EXPECT_NEAR(r.x[0], 0.981560634246719250690549090149, 1e-15);
  EXPECT_NEAR(r.w[0], 0.047175336386511827194615961485, 1e-15);
}

TEST(GaussLegendre12, IntegratesPolynomialsUpToDegree23Exactly) {
  const GaussLegendre12& r = gauss_legendre_12();
  // Integral of x^d over [a, b] is (b^(d+1) - a^(d+1)) / (d + 1).
  for (auto [a, b] : {std::pair{-1.0, 1.0}, std::pair{0.0, 1.0}, std::pair{0.3, 1.7}}) {
    for (int d = 0; d <= 23; ++d) {
      const double exact = (std::pow(b, d + 1) - std::pow(a, d + 1)) / (d + 1);
      const double got = r.integrate(a, b, [d](double x) { return std::pow(x, d); });
      EXPECT_NEAR(got, exact, 1e-14 * std::max(1.0, std::abs(exact))) << "degree " << d << " on [" << a << ", " << b << "]";
    }
  }
}

TEST(GaussLegendre12, Degree24IsNotExact) {
  // The first polynomial the rule misses: the error of x^24 on [-1, 1] is ~1e-7, far above rounding.
  const double got = gauss_legendre_12().integrate(-1.0, 1.0, [](double x) { return std::pow(x, 24); });
  EXPECT_GT(std::abs(got - 2.0 / 25), 1e-9);
}

}  // namespace
}  // namespace stampede::kernels
