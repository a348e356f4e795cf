// Tests kernels/math/chebyshev_interpolant: exact at the nodes, geometric convergence for an
// analytic function, polynomials of degree < n reproduced, bad intervals refused.
#include "kernels/math/chebyshev_interpolant.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <stdexcept>

namespace stampede::kernels {
namespace {

ChebyshevInterpolant of(double (*f)(double), double a, double b, int n) {
  std::vector<double> values;
  for (double x : ChebyshevInterpolant::nodes(a, b, n)) values.push_back(f(x));
  return ChebyshevInterpolant(a, b, std::move(values));
}

double worst_error(const ChebyshevInterpolant& p, double (*f)(double), double a, double b) {
  double worst = 0;
  for (int i = 0; i <= 1000; ++i) {
    const double x = a + (b - a) * i / 1000.0;
    worst = std::max(worst, std::abs(p(x) - f(x)));
  }
  return worst;
}

TEST(ChebyshevInterpolant, NodesLieInsideTheIntervalAndAreExact) {
  const std::vector<double> x = ChebyshevInterpolant::nodes(2.0, 5.0, 7);
  ASSERT_EQ(x.size(), 7u);
  for (double v : x) {
    EXPECT_GT(v, 2.0);
    EXPECT_LT(v, 5.0);
  }
  EXPECT_DOUBLE_EQ(x[3], 3.5);  // the middle node of an odd count is the centre
  const ChebyshevInterpolant p = of([](double t) { return std::sin(t); }, 2.0, 5.0, 7);
  for (double v : x) EXPECT_EQ(p(v), std::sin(v));
}

TEST(ChebyshevInterpolant, ConvergesGeometricallyForAnAnalyticFunction) {
  auto f = [](double t) { return std::exp(t) / (1 + t * t); };
  const double e8 = worst_error(of(f, 0, 1, 8), f, 0, 1), e16 = worst_error(of(f, 0, 1, 16), f, 0, 1);
  const double e24 = worst_error(of(f, 0, 1, 24), f, 0, 1);
  EXPECT_GT(e8, 1e-9);  // not yet converged at 8 nodes, so the drop below is a measurement
  EXPECT_LT(e16, 1e-3 * e8);
  EXPECT_LT(e24, 1e-14);
}

TEST(ChebyshevInterpolant, ReproducesPolynomialsBelowItsDegree) {
  auto cubic = [](double t) { return 1 - 2 * t + 0.5 * t * t * t; };
  const ChebyshevInterpolant p = of(cubic, -3, 2, 4);
  for (double x : {-3.0, -1.2, 0.0, 0.7, 2.0}) EXPECT_NEAR(p(x), cubic(x), 1e-12);
}

TEST(ChebyshevInterpolant, RefusesAnEmptyOrReversedInterval) {
  EXPECT_THROW(ChebyshevInterpolant::nodes(1, 1, 4), std::invalid_argument);
  EXPECT_THROW(ChebyshevInterpolant(2, 1, {1.0, 2.0}), std::invalid_argument);
  EXPECT_THROW(ChebyshevInterpolant(0, 1, {}), std::invalid_argument);
}

}  // namespace
}  // namespace stampede::kernels
