// The cubic bias fits of the noise-bias calibration: an injected polynomial bias is recovered to
// rounding without noise, and to its quoted errors with noise.
#include "kernels/polynomial_fit.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <vector>

namespace stampede::kernels {
namespace {

TEST(PolynomialFit, RecoversAnInjectedCubicExactly) {
  const double a[4] = {3e-4, -0.031, 0.004, 0.012};  // c-like, m-like and curvature terms
  std::vector<double> x, y;
  for (double e = -0.8; e <= 0.8001; e += 0.1) {
    x.push_back(e);
    y.push_back(a[0] + a[1] * e + a[2] * e * e + a[3] * e * e * e);
  }
  const PolynomialFit f = fit_polynomial(x, y, {}, 3);
  ASSERT_TRUE(f.ok());
  for (int k = 0; k < 4; ++k) EXPECT_NEAR(f.coefficients[k], a[k], 1e-14) << k;
  EXPECT_NEAR(f(0.37), a[0] + a[1] * 0.37 + a[2] * 0.37 * 0.37 + a[3] * 0.37 * 0.37 * 0.37, 1e-15);
  EXPECT_NEAR(f.derivative(0.2), a[1] + 2 * a[2] * 0.2 + 3 * a[3] * 0.04, 1e-14);
  EXPECT_LT(f.chi2, 1e-25);
}

TEST(PolynomialFit, NoisyFitIsWithinItsErrors) {
  const double a[4] = {2e-4, -0.02, 0.003, 0.01};
  const double sigma = 2e-3;
  std::vector<double> x, y, w;
  std::uint64_t state = 99;
  auto normal = [&] {  // Box-Muller on a small LCG: reproducible
    auto u = [&] {
      state = state * 6364136223846793005ull + 1442695040888963407ull;
      return (static_cast<double>(state >> 11) + 0.5) * 0x1.0p-53;
    };
    return std::sqrt(-2 * std::log(u())) * std::cos(2 * M_PI * u());
  };
  for (int rep = 0; rep < 200; ++rep)
    for (double e = -0.8; e <= 0.8001; e += 0.2) {
      x.push_back(e);
      y.push_back(a[0] + a[1] * e + a[2] * e * e + a[3] * e * e * e + sigma * normal());
      w.push_back(1 / (sigma * sigma));
    }
  const PolynomialFit f = fit_polynomial(x, y, w, 3);
  ASSERT_TRUE(f.ok());
  for (int k = 0; k < 4; ++k) {
    EXPECT_GT(f.errors[k], 0.0);
    EXPECT_LT(std::abs(f.coefficients[k] - a[k]), 4 * f.errors[k]) << k << ": " << f.coefficients[k];
  }
  // chi2 per degree of freedom ~ 1 for correct errors (1800 points: +- 0.07 at 2 sigma).
  EXPECT_NEAR(f.chi2 / (x.size() - 4), 1.0, 0.1);
}

TEST(PolynomialFit, TooFewPointsIsNotOk) {
  const std::vector<double> x = {0.1, 0.2, 0.3}, y = {1, 2, 3};
  EXPECT_FALSE(fit_polynomial(x, y, {}, 3).ok());
  EXPECT_TRUE(fit_polynomial(x, y, {}, 2).ok());
}

}  // namespace
}  // namespace stampede::kernels
