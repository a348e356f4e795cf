// Tests kernels/sersic: the incomplete gamma function, the half-light constant b_n and the analytic
// total flux, each against an independent closed form or numerical integration.
#include "kernels/sersic.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <functional>
#include <numbers>

namespace stampede::kernels {
namespace {

// Composite Simpson rule on [lo, hi] with `intervals` (even) sub-intervals. For the smooth
// integrands used here (polynomial times exponential) its error is ~h^4 max|f''''| / 180 * (hi-lo),
// far below the 1e-9 relative accuracy the tests need with the interval counts chosen below.
double simpson(const std::function<double(double)>& f, double lo, double hi, int intervals) {
  const double h = (hi - lo) / intervals;
  double sum = f(lo) + f(hi);
  for (int k = 1; k < intervals; ++k) sum += (k % 2 ? 4.0 : 2.0) * f(lo + k * h);
  return sum * h / 3.0;
}

// P(a, x) by direct quadrature of t^(a-1) e^-t / Gamma(a), independent of the series / continued
// fraction in the code under test. For non-integer a the integrand t^(a-1) is not smooth at 0 and
// Simpson would converge only like h^a; the substitution t = s^4 gives 4 s^(4a-1) e^(-s^4), at
// least four times differentiable for a >= 1, so the h^4 error bound holds (< 1e-12 here).
double gamma_p_by_quadrature(double a, double x) {
  const double integral = simpson(
      [a](double s) {
        const double s4 = s * s * s * s;
        return 4.0 * std::pow(s, 4.0 * a - 1.0) * std::exp(-s4);
      },
      0.0, std::pow(x, 0.25), 200000);
  return integral / std::tgamma(a);
}

// Tolerance for P: the series and continued fraction stop at a 1e-16 relative term and the prefactor
// exp(-x + a log x - lgamma a) carries a few ulp of its ~10-50 sized exponent, so 1e-13 absolute
// (plus 1e-12 relative for tiny P) is a few hundred ulp of headroom, not a loosened bound.
double p_tolerance(double expected) { return 1e-13 + 1e-12 * std::abs(expected); }

TEST(RegularizedGammaP, ExponentialCaseA1) {
  // P(1, x) = 1 - e^-x; both branches (series for x < 2, continued fraction beyond).
  for (double x : {1e-8, 1e-3, 0.1, 0.5, 1.0, 1.999, 2.0, 2.001, 3.0, 7.5, 20.0, 40.0}) {
    const double expected = -std::expm1(-x);
    EXPECT_NEAR(regularized_gamma_p(1.0, x), expected, p_tolerance(expected)) << "x = " << x;
  }
}

TEST(RegularizedGammaP, IntegerCaseA2) {
  // P(2, x) = 1 - (1 + x) e^-x.
  for (double x : {1e-3, 0.2, 1.0, 2.9, 3.0, 3.1, 5.0, 12.0, 30.0}) {
    const double expected = 1.0 - (1.0 + x) * std::exp(-x);
    EXPECT_NEAR(regularized_gamma_p(2.0, x), expected, p_tolerance(expected)) << "x = " << x;
  }
}

TEST(RegularizedGammaP, IntegerCaseA3) {
  // P(3, x) = 1 - (1 + x + x^2/2) e^-x.
  for (double x : {0.5, 2.0, 3.99, 4.0, 4.01, 9.0, 25.0}) {
    const double expected = 1.0 - (1.0 + x + 0.5 * x * x) * std::exp(-x);
    EXPECT_NEAR(regularized_gamma_p(3.0, x), expected, p_tolerance(expected)) << "x = " << x;
  }
}

TEST(RegularizedGammaP, HalfIntegerIsErf) {
  // P(1/2, x) = erf(sqrt(x)): a non-integer a on both sides of the branch point x = a + 1.
  for (double x : {1e-6, 0.01, 0.3, 1.0, 1.49, 1.5, 1.51, 2.5, 6.0, 15.0}) {
    const double expected = std::erf(std::sqrt(x));
    EXPECT_NEAR(regularized_gamma_p(0.5, x), expected, p_tolerance(expected)) << "x = " << x;
  }
}

TEST(RegularizedGammaP, NonIntegerAgainstQuadrature) {
  // Sérsic-relevant a = 2n for n in [0.5, 8]; the quadrature's own error is < 1e-12 here.
  for (double a : {1.0, 2.6, 5.0, 8.0, 11.3, 16.0}) {
    for (double x : {0.3 * a, a, a + 1.0, 1.7 * a + 2.0}) {
      const double expected = gamma_p_by_quadrature(a, x);
      EXPECT_NEAR(regularized_gamma_p(a, x), expected, 1e-11) << "a = " << a << " x = " << x;
    }
  }
}

TEST(RegularizedGammaP, Limits) {
  for (double a : {0.4, 1.0, 3.7, 16.0}) {
    EXPECT_EQ(regularized_gamma_p(a, 0.0), 0.0) << "a = " << a;
    EXPECT_EQ(regularized_gamma_p(a, -1.0), 0.0) << "a = " << a;
    // Far in the tail, Q < 1e-30: P must be 1 to double precision.
    EXPECT_NEAR(regularized_gamma_p(a, 200.0), 1.0, 1e-15) << "a = " << a;
    // Small x: P(a, x) ~ x^a / Gamma(a + 1).
    const double x = 1e-6;
    const double leading = std::pow(x, a) / std::tgamma(a + 1.0);
    EXPECT_NEAR(regularized_gamma_p(a, x) / leading, 1.0, 1e-5) << "a = " << a;  // next term is O(x a/(a+1))
  }
}

TEST(RegularizedGammaP, ContinuousAndMonotonicAcrossBranchPoint) {
  // The implementation switches method at x = a + 1; the two must agree there.
  for (double a : {0.7, 2.0, 8.0, 16.0}) {
    const double x = a + 1.0;
    const double below = regularized_gamma_p(a, std::nextafter(x, 0.0));
    const double at = regularized_gamma_p(a, x);
    EXPECT_NEAR(below, at, 1e-14) << "a = " << a;
    EXPECT_LT(regularized_gamma_p(a, x - 0.01), regularized_gamma_p(a, x + 0.01));
  }
}

TEST(SersicB, KnownValues) {
  // b_1 = 1.6783469900.., b_4 = 7.6692494425.. (Ciotti & Bertin 1999, tabulated to 1e-6 here).
  EXPECT_NEAR(sersic_b(1.0), 1.678347, 1e-6);
  EXPECT_NEAR(sersic_b(4.0), 7.669249, 1e-6);
  // n = 1/2 is a Gaussian: P(1, b) = 1 - e^-b = 1/2 gives b = ln 2 exactly.
  EXPECT_NEAR(sersic_b(0.5), std::numbers::ln2, 1e-13);
}

TEST(SersicB, SolvesHalfLightCondition) {
  // P(2n, b_n) = 1/2, checked with the quadrature (independent of the code's P) and with the
  // code's own P (Newton to 1e-15: the residual is a few ulp).
  for (double n : {0.5, 0.8, 1.0, 1.5, 2.0, 2.5, 3.3, 4.0, 5.5, 8.0}) {
    const double b = sersic_b(n);
    EXPECT_NEAR(gamma_p_by_quadrature(2.0 * n, b), 0.5, 1e-11) << "n = " << n;
    EXPECT_NEAR(regularized_gamma_p(2.0 * n, b), 0.5, 1e-14) << "n = " << n;
    // Ciotti & Bertin's asymptotic series is accurate to < 1e-3 for n >= 0.5: a sanity bracket.
    const double asymptotic = 2.0 * n - 1.0 / 3.0 + 4.0 / (405.0 * n) + 46.0 / (25515.0 * n * n);
    EXPECT_NEAR(b, asymptotic, 2e-3) << "n = " << n;
  }
}

// 2 pi n r_e^2 A int_0^T t^(2n-1) exp(-b t) dt: the radial flux integral 2 pi int I(r) r dr after
// the substitution r = r_e t^n (smooth integrand for the integer 2n - 1 used here).
double radial_flux(double amplitude, double re, double n, double t_max) {
  const double b = sersic_b(n);
  const double integral = simpson([n, b](double t) { return std::pow(t, 2.0 * n - 1.0) * std::exp(-b * t); }, 0.0,
                                  t_max, 400000);
  return 2.0 * std::numbers::pi * n * re * re * amplitude * integral;
}

TEST(SersicFlux, MatchesNumericalRadialIntegration) {
  // Upper limit t = 200 / b: the neglected tail is < t^(2n-1) e^-200, i.e. < 1e-70 of the total.
  for (double n : {1.0, 4.0, 2.5}) {
    for (double re : {0.7, 2.0, 5.3}) {
      const double amplitude = 37.5;
      const double numeric = radial_flux(amplitude, re, n, 200.0 / sersic_b(n));
      const double analytic = sersic_flux(amplitude, re, n);
      EXPECT_NEAR(analytic / numeric, 1.0, 1e-6) << "n = " << n << " re = " << re;
      EXPECT_NEAR(sersic_flux_per_amplitude(re, n) * amplitude / analytic, 1.0, 1e-15);
    }
  }
}

TEST(SersicFlux, MatchesDirectIntegrationInRadius) {
  // Without substitution for the exponential disc: 2 pi int_0^R A exp(-b r / r_e) r dr, R = 60 r_e
  // (tail ~ e^-100). The integrand has no cusp in r, Simpson converges to ~1e-12.
  const double re = 1.6, amplitude = 2.0, b = sersic_b(1.0);
  const double numeric = 2.0 * std::numbers::pi *
                         simpson([&](double r) { return amplitude * std::exp(-b * r / re) * r; }, 0.0, 60.0 * re,
                                 400000);
  EXPECT_NEAR(sersic_flux(amplitude, re, 1.0) / numeric, 1.0, 1e-9);
}

TEST(SersicFlux, HalfTheFluxLiesInsideHalfLightRadius) {
  for (double n : {1.0, 2.5, 4.0}) {
    const double re = 1.9, amplitude = 5.0;
    const double inside = radial_flux(amplitude, re, n, 1.0);  // t <= 1  <=>  r <= r_e
    // Simpson on [0, 1] with 4e5 intervals: error < 1e-15 relative.
    EXPECT_NEAR(inside / sersic_flux(amplitude, re, n), 0.5, 1e-9) << "n = " << n;
  }
}

TEST(SersicFlux, ScalesWithAmplitudeAndRadiusSquared) {
  const double f = sersic_flux(1.0, 1.0, 4.0);
  EXPECT_NEAR(sersic_flux(3.0, 1.0, 4.0) / f, 3.0, 1e-14);
  EXPECT_NEAR(sersic_flux(1.0, 2.5, 4.0) / f, 6.25, 1e-14);
  // The exponential disc's closed form: 2 pi r_e^2 A / b_1^2.
  const double b1 = sersic_b(1.0);
  EXPECT_NEAR(sersic_flux(1.0, 1.0, 1.0), 2.0 * std::numbers::pi / (b1 * b1), 1e-14);
}

}  // namespace
}  // namespace stampede::kernels
