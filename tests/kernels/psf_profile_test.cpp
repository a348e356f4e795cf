// Tests kernels/psf_profile: the Moffat and Airy profiles' shape (FWHM, zeros, peak) and their
// analytic normalisation, checked by summing the wrapped samples against closed-form encircled
// energies; and the wrapped lag layout the FFT convolution relies on.
#include "kernels/psf_profile.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <functional>
#include <numbers>
#include <vector>

#include "kernels/ellipse.hpp"

namespace stampede::kernels {
namespace {

constexpr double kPi = std::numbers::pi;

// Lag of wrapped index i on an n-point grid, written independently of the code under test.
double lag(int i, int n, double step) { return (2 * i < n ? i : i - n) * step; }

std::vector<double> moffat_grid(const MoffatProfile& psf, int n, double step) {
  std::vector<double> out(static_cast<std::size_t>(n) * n);
  sample_moffat_wrapped(psf, n, step, out.data());
  return out;
}

double total(const std::vector<double>& v) {
  double s = 0.0;
  for (double x : v) s += x;
  return s;
}

// Sum of the samples whose lag satisfies `inside`.
double aperture_sum(const std::vector<double>& v, int n, double step, const std::function<bool(double, double)>& inside) {
  double s = 0.0;
  for (int j = 0; j < n; ++j)
    for (int i = 0; i < n; ++i)
      if (inside(lag(i, n, step), lag(j, n, step))) s += v[static_cast<std::size_t>(j) * n + i];
  return s;
}

// Fraction of a round Moffat's flux inside radius R: 1 - (1 + (R/alpha)^2)^(1-beta).
double moffat_enclosed(double radius, double alpha, double beta) {
  return 1.0 - std::pow(1.0 + (radius / alpha) * (radius / alpha), 1.0 - beta);
}

TEST(Moffat, AlphaFromFwhm) {
  // alpha = fwhm / (2 sqrt(2^(1/beta) - 1)); for beta = 1 (Lorentzian) alpha = fwhm / 2.
  EXPECT_NEAR(moffat_alpha(3.0, 1.0), 1.5, 1e-15);
  EXPECT_NEAR(moffat_alpha(2.85, 3.0), 2.85 / (2.0 * std::sqrt(std::cbrt(2.0) - 1.0)), 1e-14);
}

TEST(Moffat, HalfMaximumAtHalfFwhm) {
  // (1 + u)^-beta = 1/2 at u = 2^(1/beta) - 1: a handful of ulp, so 1e-12.
  for (double beta : {1.5, 2.5, 3.0, 4.765}) {
    for (double fwhm : {1.0, 2.85, 6.0}) {
      const MoffatProfile psf{beta, fwhm, 0.0, 0.0, 0.0};
      const double peak = moffat_intensity(psf, 0.0, 0.0);
      EXPECT_NEAR(moffat_intensity(psf, fwhm / 2, 0.0) / peak, 0.5, 1e-12) << "beta " << beta << " fwhm " << fwhm;
      const double d = fwhm / 2 / std::sqrt(2.0);
      EXPECT_NEAR(moffat_intensity(psf, -d, d) / peak, 0.5, 1e-12);
      // Analytic peak of the unit-flux profile.
      const double alpha = moffat_alpha(fwhm, beta);
      EXPECT_NEAR(peak, (beta - 1.0) / (kPi * alpha * alpha), 1e-14 * peak);
    }
  }
}

TEST(Moffat, ShearedHalfMaximumOnSemiAxes) {
  // e = |e| (cos 2 theta, sin 2 theta): half maximum at a = (fwhm/2) sqrt((1+|e|)/(1-|e|)) along theta
  // and b = (fwhm/2) sqrt((1-|e|)/(1+|e|)) across it; the peak is unchanged (area-preserving).
  const double mod = 0.3, theta = 0.6;
  const MoffatProfile round{3.0, 2.85, 0.0, 0.0, 0.0};
  const MoffatProfile psf{3.0, 2.85, mod * std::cos(2 * theta), mod * std::sin(2 * theta), 0.0};
  const double peak = moffat_intensity(psf, 0.0, 0.0);
  EXPECT_NEAR(peak, moffat_intensity(round, 0.0, 0.0), 1e-15);
  const double a = 2.85 / 2 * std::sqrt((1 + mod) / (1 - mod)), b = 2.85 / 2 * std::sqrt((1 - mod) / (1 + mod));
  EXPECT_NEAR(moffat_intensity(psf, a * std::cos(theta), a * std::sin(theta)) / peak, 0.5, 1e-12);
  EXPECT_NEAR(moffat_intensity(psf, -b * std::sin(theta), b * std::cos(theta)) / peak, 0.5, 1e-12);
  // e1 > 0 elongates along x.
  const MoffatProfile along_x{3.0, 2.85, 0.2, 0.0, 0.0};
  EXPECT_GT(moffat_intensity(along_x, 2.0, 0.0), moffat_intensity(along_x, 0.0, 2.0));
}

// Flux of a round Moffat inside the square [-L, L]^2 from the closed-form enclosed flux: a wedge dphi
// reaching radius rho holds enclosed(rho) dphi / (2 pi), so F = (4 / pi) int_0^(pi/4) enclosed(L / cos
// phi) dphi. The phi integrand is smooth; Simpson with 2000 intervals is exact to ~1e-14.
double moffat_in_square(double half_side, double alpha, double beta) {
  const int intervals = 2000;
  const double h = (kPi / 4) / intervals;
  double sum = 0.0;
  for (int k = 0; k <= intervals; ++k) {
    const double f = moffat_enclosed(half_side / std::cos(k * h), alpha, beta);
    sum += (k == 0 || k == intervals ? 1.0 : (k % 2 ? 4.0 : 2.0)) * f;
  }
  return (4.0 / kPi) * sum * h / 3.0;
}

TEST(Moffat, WrappedSumMatchesAnalyticEnclosedFlux) {
  // Odd n = 511, step 0.1: lags -255..255, so the cells tile the square [-25.55, 25.55]^2 exactly and
  // the samples' sum is the midpoint rule for the flux in that square (the samples are flux per
  // sub-pixel). Sub-squares of K cells either side tile [-(K+1/2) h, (K+1/2) h]^2. The midpoint rule's
  // leading error is (h^2 / 24) times the outward flux of grad I through the square's edge,
  // < (h^2/24) 8 L |dI/dr|(L) < 5e-7 for L >= 15 px and the betas below (alpha ~ 2.6-3.4 px); the
  // closed form is therefore checked to 1e-6, and a wrong normalisation or alpha would miss by >1e-3.
  const double step = 0.1;
  const int n = 511;
  for (double beta : {2.5, 3.0, 4.5}) {
    const MoffatProfile psf{beta, 2.85, 0.0, 0.0, 0.0};
    const double alpha = moffat_alpha(psf.fwhm, beta);
    const std::vector<double> v = moffat_grid(psf, n, step);
    EXPECT_NEAR(total(v), moffat_in_square(25.55, alpha, beta), 1e-6) << "beta " << beta;
    for (int k : {150, 200, 230}) {
      const double limit = (k + 0.25) * step;  // between the last included and first excluded lag
      const double in_square =
          aperture_sum(v, n, step, [limit](double x, double y) { return std::abs(x) < limit && std::abs(y) < limit; });
      EXPECT_NEAR(in_square, moffat_in_square((k + 0.5) * step, alpha, beta), 1e-6) << "beta " << beta << " K " << k;
    }
    // And the brief's disc bound: the square lies between its inscribed and circumscribed discs.
    EXPECT_GT(total(v), moffat_enclosed(25.55, alpha, beta));
    EXPECT_LT(total(v), moffat_enclosed(25.55 * std::sqrt(2.0), alpha, beta));
  }
}

TEST(Moffat, ShearedHasSameFluxAsRound) {
  // Area preservation. beta = 4.5 and n = 1023 (+-51.15 px): the flux outside the largest
  // sheared-profile contour inside the square is (1 + u0)^(1-beta), u0 = (51.15 / alpha)^2
  // (1-|e|)/(1+|e|) ~ 170, i.e. < 2e-8, and the midpoint-rule error is negligible that far out; so
  // both sums equal 1 to 1e-6 (a shear that did not preserve area would change the sum by ~|e|^2).
  const double step = 0.1;
  const int n = 1023;
  for (const MoffatProfile& psf : {MoffatProfile{4.5, 2.85, 0.0, 0.0, 0.0}, MoffatProfile{4.5, 2.85, 0.25, -0.2, 0.0},
                                   MoffatProfile{4.5, 2.85, -0.4, 0.1, 0.0}}) {
    EXPECT_NEAR(total(moffat_grid(psf, n, step)), 1.0, 1e-6) << "e = (" << psf.e1 << ", " << psf.e2 << ")";
  }
  // beta = 3 on the 511 grid: both miss at most (1 + u0)^-2 with u0 = (25.55/alpha)^2 0.515 = 43,
  // i.e. 5.2e-4, so they agree to that.
  const std::vector<double> round = moffat_grid(MoffatProfile{3.0, 2.85, 0.0, 0.0, 0.0}, 511, step);
  const std::vector<double> sheared = moffat_grid(MoffatProfile{3.0, 2.85, 0.25, -0.2, 0.0}, 511, step);
  EXPECT_NEAR(total(sheared), total(round), 5.2e-4);
}

TEST(Moffat, TruncatedProfileSumsToOne) {
  // All flux within the truncation radius (10 px < 25.5 px grid half-size), renormalised to 1. The
  // sharp edge makes the sum's error that of counting samples along the boundary: at most the flux
  // in a ring of width h/sqrt(2) at I(10 px) ~ 1.5e-5 / px^2, 2 pi 10 0.07 1.5e-5 = 7e-5 < 1e-4.
  const double step = 0.1;
  const int n = 512;
  for (double e1 : {0.0, 0.2}) {
    const MoffatProfile psf{3.0, 2.85, e1, -0.1, 10.0};
    const std::vector<double> v = moffat_grid(psf, n, step);
    EXPECT_NEAR(total(v), 1.0, 1e-4) << "e1 = " << e1;
    // Nothing beyond the truncation radius (in the unsheared frame).
    const double alpha = moffat_alpha(psf.fwhm, psf.beta);
    const EllipseQuadratic q = ellipse_quadratic(psf.e1, psf.e2, alpha);
    const double u_max = (10.0 / alpha) * (10.0 / alpha);
    EXPECT_EQ(aperture_sum(v, n, step, [&](double x, double y) { return q(x, y) > u_max * (1 + 1e-9); }), 0.0);
    // Inside it, the truncated profile is the untruncated one scaled by 1 / enclosed(10).
    const MoffatProfile untruncated{3.0, 2.85, e1, -0.1, 0.0};
    EXPECT_NEAR(moffat_intensity(psf, 1.0, 2.0) / moffat_intensity(untruncated, 1.0, 2.0),
                1.0 / moffat_enclosed(10.0, alpha, 3.0), 1e-13);
  }
}

TEST(Moffat, WrappedLayout) {
  const double step = 0.3;
  for (int n : {8, 9}) {
    const MoffatProfile psf{3.0, 2.85, 0.15, 0.1, 0.0};
    const std::vector<double> v = moffat_grid(psf, n, step);
    const double area = step * step;
    // Lag 0 at index 0, and each sample is intensity * step^2 at its wrapped lag.
    EXPECT_NEAR(v[0], area * moffat_intensity(psf, 0.0, 0.0), 1e-15);
    for (int j = 0; j < n; ++j)
      for (int i = 0; i < n; ++i)
        EXPECT_NEAR(v[j * n + i], area * moffat_intensity(psf, lag(i, n, step), lag(j, n, step)), 1e-15)
            << "n " << n << " (" << i << ", " << j << ")";
    // Point symmetry I(x, y) = I(-x, -y): index (i, j) <-> ((n - i) % n, (n - j) % n), except where
    // the even grid's Nyquist lag -n/2 has no positive partner.
    for (int j = 0; j < n; ++j)
      for (int i = 0; i < n; ++i) {
        if (n % 2 == 0 && (2 * i == n || 2 * j == n)) continue;
        EXPECT_EQ(v[j * n + i], v[((n - j) % n) * n + (n - i) % n]) << "n " << n << " (" << i << ", " << j << ")";
      }
  }
  // Round profile: mirror symmetric in each axis separately, i <-> n - i.
  const int n = 10;
  const std::vector<double> v = moffat_grid(MoffatProfile{}, n, step);
  for (int j = 0; j < n; ++j)
    for (int i = 1; i < n; ++i) EXPECT_EQ(v[j * n + i], v[j * n + (n - i)]) << "(" << i << ", " << j << ")";
}

// Encircled energy of the unobscured Airy disc: 1 - J0(x)^2 - J1(x)^2, x = pi R / L (Rayleigh).
double airy_encircled(double radius, double lambda_over_d) {
  const double x = kPi * radius / lambda_over_d;
  const double j0 = std::cyl_bessel_j(0.0, x), j1 = std::cyl_bessel_j(1.0, x);
  return 1.0 - j0 * j0 - j1 * j1;
}

TEST(Airy, PeakAndFirstDarkRing) {
  for (double eps : {0.0, 0.3}) {
    const double lod = 2.0;
    const AiryProfile psf{lod, eps};
    // Unit-flux peak of an annular aperture: pi (1 - eps^2) / (4 L^2).
    const double peak = kPi * (1 - eps * eps) / (4 * lod * lod);
    EXPECT_NEAR(airy_intensity(psf, 0.0, 0.0), peak, 1e-15) << "eps " << eps;
    // Continuous through the small-x branch (x < 1e-8): the profile is flat there to O(x^2).
    EXPECT_NEAR(airy_intensity(psf, 1e-7, 0.0), peak, 1e-12 * peak) << "eps " << eps;
  }
  // Unobscured: the first zero of J1 (x = 3.8317) is at r = 1.21967 L; 1.21967 is rounded to 6
  // digits, so J1 there is ~1e-6 and I / I(0) = (2 J1 / x)^2 ~ 1e-12.
  const AiryProfile psf{2.0, 0.0};
  const double peak = airy_intensity(psf, 0, 0);
  const double r0 = 1.21967 * 2.0;
  EXPECT_LT(airy_intensity(psf, r0, 0.0) / peak, 1e-10);
  EXPECT_LT(airy_intensity(psf, 0.0, -r0) / peak, 1e-10);
  EXPECT_GT(airy_intensity(psf, r0 - 0.1, 0.0), airy_intensity(psf, r0, 0.0));
  EXPECT_GT(airy_intensity(psf, r0 + 0.1, 0.0), airy_intensity(psf, r0, 0.0));
  // And the first bright ring (x = 5.1356) carries 1.75% of the peak intensity.
  EXPECT_NEAR(airy_intensity(psf, 5.1356 * 2.0 / kPi, 0.0) / peak, 0.0175, 2e-4);
}

TEST(Airy, WrappedSumMatchesEncircledEnergy) {
  // Unobscured, L = 2 px, step 0.1 px (20 samples per L), discs whose radii are dark rings (zeros of
  // J1): intensity and gradient vanish on the boundary, so the midpoint rule's h^2 boundary term drops
  // out and the jagged lattice boundary only misplaces cells holding I ~ I''(R) (h/2)^2 / 2, whose
  // errors largely cancel (lattice-point discrepancy). From the 2nd ring on this is < 5e-8 at this
  // step (I'' falls like x^-3; the 1st ring, with the steepest I'', reaches ~1e-6 and is left out).
  // Tolerance 1e-6; a normalisation or scale error in the profile would miss by > 1e-3.
  const double step = 0.1, lod = 2.0;
  const int n = 512;
  std::vector<double> v(static_cast<std::size_t>(n) * n);
  sample_airy_wrapped(AiryProfile{lod, 0.0}, n, step, v.data());
  for (double j1_zero : {7.0155866698, 10.1734681351, 13.3236919363, 25.9036720876, 38.4747662348}) {
    const double radius = j1_zero * lod / kPi;
    const double in_disc = aperture_sum(v, n, step, [radius](double x, double y) { return x * x + y * y <= radius * radius; });
    EXPECT_NEAR(in_disc, airy_encircled(radius, lod), 1e-6) << "R = " << radius;
  }
  // Lag layout as for the Moffat: sample (i, j) is I(lag_i, lag_j) step^2.
  EXPECT_NEAR(v[0], step * step * airy_intensity(AiryProfile{lod, 0.0}, 0, 0), 1e-16);
  EXPECT_NEAR(v[3 * n + (n - 5)], step * step * airy_intensity(AiryProfile{lod, 0.0}, -0.5, 0.3), 1e-16);
}

TEST(Airy, RadialIntegralTendsToOne) {
  // Independent of the 2D sampling: 2 pi int_0^Rmax I(r) r dr by Simpson (step L/200, accurate to
  // ~1e-10 for a profile oscillating on the scale L), plus the analytic tail beyond Rmax. For large
  // x the cycle-averaged amplitude^2 is (4/x^2)(J1(x)^2 + eps^2 J1(eps x)^2) ~ 4 (1 + eps) / (pi x^3),
  // so the flux beyond X = pi Rmax / L is 2 / (pi (1 - eps) X) (1 - J0^2 - J1^2 -> 1 - 2/(pi x) for
  // eps = 0), with O(1/X^2) ~ 1e-5 corrections from the oscillation: tolerance 5e-5.
  for (double eps : {0.0, 0.3}) {
    const double lod = 1.5;
    const AiryProfile psf{lod, eps};
    const double r_max = 100.0 * lod;
    const int intervals = 40000;
    const double h = r_max / intervals;
    double sum = 0.0;
    for (int k = 0; k <= intervals; ++k) {
      const double r = k * h;
      const double f = airy_intensity(psf, r, 0.0) * r;
      sum += (k == 0 || k == intervals ? 1.0 : (k % 2 ? 4.0 : 2.0)) * f;
    }
    const double inside = 2.0 * kPi * sum * h / 3.0;
    const double x_max = kPi * r_max / lod;
    const double tail = 2.0 / (kPi * (1.0 - eps) * x_max);
    EXPECT_NEAR(inside + tail, 1.0, 5e-5) << "eps " << eps;
    if (eps == 0.0) {
      EXPECT_NEAR(inside, airy_encircled(r_max, lod), 1e-8);
    }
  }
}

}  // namespace
}  // namespace stampede::kernels
