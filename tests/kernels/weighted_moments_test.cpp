// Tests kernels/weighted_moments: an elliptical Gaussian anywhere in the stamp gives the moments of
// its product with the round weight (analytic: the inverse covariances add) about its own centre;
// the stated errors match the scatter over noise realisations; no positive flux is invalid.
#include "kernels/weighted_moments.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <numbers>
#include <random>
#include <vector>

namespace stampede::kernels {
namespace {

constexpr int kSize = 48;

// Point-sampled at pixel centres: with sigma >= 2 px the sampled moments are the continuous ones
// to far below these tolerances (moments_test).
std::vector<double> gaussian(double x0, double y0, double cxx, double cxy, double cyy, double flux) {
  const double det = cxx * cyy - cxy * cxy;
  const double ixx = cyy / det, iyy = cxx / det, ixy = -cxy / det;
  std::vector<double> img(kSize * kSize);
  for (int j = 0; j < kSize; ++j)
    for (int i = 0; i < kSize; ++i) {
      const double dx = i - x0, dy = j - y0;
      img[j * kSize + i] = flux / (2 * std::numbers::pi * std::sqrt(det)) *
                           std::exp(-0.5 * (ixx * dx * dx + 2 * ixy * dx * dy + iyy * dy * dy));
    }
  return img;
}

TEST(WeightedMoments, AGaussianAnywhereGivesItsProductWithTheWeight) {
  std::vector<double> scratch(2 * kSize);
  const double fwhm = 7.0, w = std::pow(fwhm / 2.3548200450309493, 2);
  const double cxx = 9.0, cxy = 2.5, cyy = 5.0;
  for (double offset : {0.0, 0.37, -1.8, 3.2}) {
    const double x0 = 23.5 + offset, y0 = 23.5 - 0.6 * offset;
    const WeightedMoments m = weighted_moments(gaussian(x0, y0, cxx, cxy, cyy, 1000), kSize, fwhm, 0.0, scratch);
    ASSERT_TRUE(m.valid);
    // Product covariance P = (C^-1 + I / w)^-1.
    const double det = cxx * cyy - cxy * cxy;
    const double a = cyy / det + 1 / w, b = -cxy / det, d = cxx / det + 1 / w, pd = a * d - b * b;
    const double pxx = d / pd, pxy = -b / pd, pyy = a / pd;
    EXPECT_NEAR(m.x, x0, 1e-7) << offset;
    EXPECT_NEAR(m.y, y0, 1e-7) << offset;
    EXPECT_NEAR(m.t, pxx + pyy, 1e-7 * (pxx + pyy)) << offset;
    EXPECT_NEAR(m.e1, (pxx - pyy) / (pxx + pyy), 1e-8) << offset;
    EXPECT_NEAR(m.e2, 2 * pxy / (pxx + pyy), 1e-8) << offset;
    EXPECT_TRUE(std::isinf(m.snr));
  }
}

TEST(WeightedMoments, ErrorsAndSnrMatchTheScatterOverNoise) {
  std::vector<double> scratch(2 * kSize);
  const std::vector<double> truth = gaussian(24.1, 23.2, 6.0, 1.0, 4.0, 600);
  std::mt19937 rng(5);
  std::normal_distribution<double> noise(0, 1);
  const int n = 2000;
  double s1 = 0, s11 = 0, s2 = 0, s22 = 0, sf = 0, sff = 0, err1 = 0, err2 = 0, snr = 0;
  std::vector<double> img(truth.size());
  for (int k = 0; k < n; ++k) {
    for (std::size_t i = 0; i < img.size(); ++i) img[i] = truth[i] + noise(rng);
    const WeightedMoments m = weighted_moments(img, kSize, 6.0, 1.0, scratch);
    ASSERT_TRUE(m.valid);
    s1 += m.e1, s11 += m.e1 * m.e1, s2 += m.e2, s22 += m.e2 * m.e2, sf += m.flux, sff += m.flux * m.flux;
    err1 += m.e1_err / n, err2 += m.e2_err / n, snr += m.snr / n;
  }
  const double sd1 = std::sqrt(s11 / n - s1 * s1 / n / n), sd2 = std::sqrt(s22 / n - s2 * s2 / n / n);
  const double mean_flux = sf / n, sd_flux = std::sqrt(sff / n - mean_flux * mean_flux);
  std::printf("e1 sd %.4e stated %.4e; e2 sd %.4e stated %.4e; S/N measured %.2f stated %.2f\n", sd1, err1, sd2, err2,
              mean_flux / sd_flux, snr);
  // The stated errors hold the centroid fixed; it moves with the noise too, which adds little at
  // this S/N. 2,000 realisations measure a standard deviation to ~1.6 %.
  EXPECT_NEAR(err1 / sd1, 1, 0.08);
  EXPECT_NEAR(err2 / sd2, 1, 0.08);
  EXPECT_NEAR(snr / (mean_flux / sd_flux), 1, 0.08);
}

TEST(WeightedMoments, NoPositiveFluxOrABadWeightIsInvalid) {
  std::vector<double> scratch(2 * kSize);
  const std::vector<double> zero(kSize * kSize, 0.0), negative(kSize * kSize, -1.0);
  EXPECT_FALSE(weighted_moments(zero, kSize, 5.0, 1.0, scratch).valid);
  EXPECT_FALSE(weighted_moments(negative, kSize, 5.0, 1.0, scratch).valid);
  const std::vector<double> g = gaussian(23.5, 23.5, 4, 0, 4, 100);
  EXPECT_FALSE(weighted_moments(g, kSize, 0.0, 1.0, scratch).valid);
  std::vector<double> short_scratch(kSize);
  EXPECT_FALSE(weighted_moments(g, kSize, 5.0, 1.0, short_scratch).valid);
  EXPECT_TRUE(weighted_moments(g, kSize, 5.0, 1.0, scratch).valid);
}

}  // namespace
}  // namespace stampede::kernels
