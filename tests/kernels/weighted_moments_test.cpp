// Tests kernels/weighted_moments: an elliptical Gaussian anywhere in the stamp gives the moments of
// its product with the round weight (analytic: the inverse covariances add) about its own centre;
// the stated errors match the scatter over noise realisations; no positive flux is invalid. An
// object seen in several stamps through different WCS Jacobians is measured on the sky: the
// combination gives the sky profile's moments, and its stated errors match its scatter.
#include "kernels/weighted_moments.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <numbers>
#include <random>
#include <utility>
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

TEST(WeightedMoments, AHeldWeightGivesTheMomentsAboutWhereItStarts) {
  // No Newton steps: the weight stays at (sx, sy), and the moments are the product's second moments
  // about that point, P + (m - s)(m - s)^T, m = P (C^-1 mu + s / w) the product's mean.
  std::vector<double> scratch(2 * kSize);
  const double fwhm = 7.0, w = std::pow(fwhm / 2.3548200450309493, 2);
  const double cxx = 9.0, cxy = 2.5, cyy = 5.0, x0 = 23.8, y0 = 22.9;
  const double det = cxx * cyy - cxy * cxy, ixx = cyy / det, ixy = -cxy / det, iyy = cxx / det;
  const double a = ixx + 1 / w, b = ixy, d = iyy + 1 / w, pd = a * d - b * b;
  const double pxx = d / pd, pxy = -b / pd, pyy = a / pd;
  for (const auto& [sx, sy] : {std::pair{23.8, 22.9}, std::pair{24.6, 22.1}, std::pair{21.0, 24.0}}) {
    const WeightedMoments m =
        weighted_moments(gaussian(x0, y0, cxx, cxy, cyy, 1000), kSize, fwhm, 0.0, scratch, 0, sx, sy);
    ASSERT_TRUE(m.valid);
    EXPECT_EQ(m.x, sx);
    EXPECT_EQ(m.y, sy);
    const double vx = ixx * x0 + ixy * y0 + sx / w, vy = ixy * x0 + iyy * y0 + sy / w;
    const double mx = pxx * vx + pxy * vy - sx, my = pxy * vx + pyy * vy - sy;
    const double mxx = pxx + mx * mx, mxy = pxy + mx * my, myy = pyy + my * my;
    EXPECT_NEAR(m.t, mxx + myy, 1e-7 * (mxx + myy)) << sx;
    EXPECT_NEAR(m.e1, (mxx - myy) / (mxx + myy), 1e-8) << sx;
    EXPECT_NEAR(m.e2, 2 * mxy / (mxx + myy), 1e-8) << sx;
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

// An axis-aligned Jacobian's errors come from one-axis sums (the separable weight); a Jacobian off
// the axes by 1e-300 takes the per-pixel sums with the same weight: the same errors and S/N.
TEST(WeightedMoments, TheSeparableErrorsAreThePerPixelSums) {
  std::vector<double> scratch;
  const std::vector<double> img = gaussian(22.3, 25.1, 9.0, 2.5, 5.0, 1000);
  for (const auto& [dudx, dvdy] : {std::pair{1.0, 1.0}, {0.27, 0.25}}) {
    MomentsStamp a{img, kSize, dudx, 0.0, 0.0, dvdy, 23.5, 23.5, 1.0, 0.7};
    MomentsStamp b = a;
    b.dudy = 1e-300;
    const WeightedMoments ma = weighted_moments({&a, 1}, 7.0 * dudx, scratch, 0),
                          mb = weighted_moments({&b, 1}, 7.0 * dudx, scratch, 0);
    ASSERT_TRUE(ma.valid && mb.valid);
    EXPECT_NEAR(ma.e1_err, mb.e1_err, 1e-12 * mb.e1_err) << dudx;
    EXPECT_NEAR(ma.e2_err, mb.e2_err, 1e-12 * mb.e2_err) << dudx;
    EXPECT_NEAR(ma.snr, mb.snr, 1e-12 * mb.snr) << dudx;
    EXPECT_NEAR(ma.e1, mb.e1, 1e-13) << dudx;  // the weighted sums too, separable or per pixel
  }
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

// A sky Gaussian (covariance c, arcsec^2, centre u0 v0) as pixel fluxes of a stamp whose pixel
// (x, y) lies at J (x - x_ref, y - y_ref): flux_scale x surface brightness x |det J|.
struct SkyStamp {
  MomentsStamp stamp;
  std::vector<double> pixels;
};
SkyStamp sky_stamp(double flux, double u0, double v0, const double c[3], const double j[4], double x_ref, double y_ref,
                   double flux_scale) {
  SkyStamp out;
  out.pixels.resize(kSize * kSize);
  const double det = c[0] * c[2] - c[1] * c[1], area = std::abs(j[0] * j[3] - j[1] * j[2]);
  for (int y = 0; y < kSize; ++y)
    for (int x = 0; x < kSize; ++x) {
      const double u = j[0] * (x - x_ref) + j[1] * (y - y_ref) - u0, v = j[2] * (x - x_ref) + j[3] * (y - y_ref) - v0;
      const double q = (c[2] * u * u - 2 * c[1] * u * v + c[0] * v * v) / det;
      out.pixels[y * kSize + x] = flux_scale * area * flux / (2 * std::numbers::pi * std::sqrt(det)) * std::exp(-0.5 * q);
    }
  out.stamp = {out.pixels, kSize, j[0], j[1], j[2], j[3], x_ref, y_ref, flux_scale, 0.0};
  return out;
}

// Three stamps: 0.26"/px rotated and sheared, 0.2"/px axis-aligned (the separable path), 0.3"/px
// flipped; each with the object a fraction of a pixel from its reference.
const double kJacobians[3][4] = {{0.21, -0.15, 0.16, 0.2}, {0.2, 0.0, 0.0, 0.2}, {0.0, 0.3, 0.31, 0.0}};
const double kRefs[3][2] = {{23.3, 24.1}, {22.8, 23.6}, {24.4, 23.2}};
const double kScales[3] = {1.0, 2.5, 0.7};

TEST(WeightedMoments, StampsThroughSeveralJacobiansGiveTheSkysMoments) {
  const double c[3] = {0.5, 0.12, 0.3}, u0 = 0.07, v0 = -0.11, fwhm = 1.4, w = std::pow(fwhm / 2.3548200450309493, 2);
  std::vector<SkyStamp> sky;
  for (int k = 0; k < 3; ++k) sky.push_back(sky_stamp(100, u0, v0, c, kJacobians[k], kRefs[k][0], kRefs[k][1], kScales[k]));
  const double det = c[0] * c[2] - c[1] * c[1];
  const double a = c[2] / det + 1 / w, b = -c[1] / det, d = c[0] / det + 1 / w, pd = a * d - b * b;
  const double puu = d / pd, puv = -b / pd, pvv = a / pd;
  const double flux = 100 * std::sqrt(1 / pd / det);  // the weighted flux: F sqrt(det P / det C)
  std::vector<double> scratch;
  for (std::size_t n = 1; n <= 3; ++n) {
    std::vector<MomentsStamp> stamps;
    for (std::size_t k = 0; k < n; ++k) stamps.push_back(sky[k].stamp);
    const WeightedMoments m = weighted_moments(stamps, fwhm, scratch);
    ASSERT_TRUE(m.valid) << n;
    EXPECT_NEAR(m.x, u0, 1e-7) << n;
    EXPECT_NEAR(m.y, v0, 1e-7) << n;
    EXPECT_NEAR(m.flux, flux, 1e-6 * flux) << n;
    EXPECT_NEAR(m.t, puu + pvv, 1e-6 * (puu + pvv)) << n;
    EXPECT_NEAR(m.e1, (puu - pvv) / (puu + pvv), 1e-7) << n;
    EXPECT_NEAR(m.e2, 2 * puv / (puu + pvv), 1e-7) << n;
    // Each stamp alone gives the same sky moments.
    const WeightedMoments one = weighted_moments({&sky[n - 1].stamp, 1}, fwhm, scratch);
    EXPECT_NEAR(one.e1, m.e1, 1e-7) << n;
    EXPECT_NEAR(one.e2, m.e2, 1e-7) << n;
  }
}

TEST(WeightedMoments, SeveralStampsErrorsMatchTheScatterOverNoise) {
  const double c[3] = {0.4, -0.05, 0.35}, fwhm = 1.5;
  const double sigma[3] = {0.5, 1.0, 2.0};  // per-pixel noise: the stamps are weighted unequally
  std::vector<SkyStamp> sky;
  for (int k = 0; k < 3; ++k) {
    sky.push_back(sky_stamp(60, 0.02, 0.03, c, kJacobians[k], kRefs[k][0], kRefs[k][1], kScales[k]));
    sky.back().stamp.variance = sigma[k] * sigma[k];
  }
  std::mt19937 rng(11);
  std::normal_distribution<double> noise(0, 1);
  const int n = 1500;
  std::vector<std::vector<double>> noisy(3, std::vector<double>(kSize * kSize));
  std::vector<MomentsStamp> stamps(3);
  std::vector<double> scratch;
  double s1 = 0, s11 = 0, s2 = 0, s22 = 0, sf = 0, sff = 0, err1 = 0, err2 = 0, snr = 0;
  for (int r = 0; r < n; ++r) {
    for (int k = 0; k < 3; ++k) {
      for (std::size_t i = 0; i < noisy[k].size(); ++i) noisy[k][i] = sky[k].pixels[i] + sigma[k] * noise(rng);
      stamps[k] = sky[k].stamp;
      stamps[k].image = noisy[k];
    }
    const WeightedMoments m = weighted_moments(stamps, fwhm, scratch);
    ASSERT_TRUE(m.valid);
    s1 += m.e1, s11 += m.e1 * m.e1, s2 += m.e2, s22 += m.e2 * m.e2, sf += m.flux, sff += m.flux * m.flux;
    err1 += m.e1_err / n, err2 += m.e2_err / n, snr += m.snr / n;
  }
  const double sd1 = std::sqrt(s11 / n - s1 * s1 / n / n), sd2 = std::sqrt(s22 / n - s2 * s2 / n / n);
  const double mean_flux = sf / n, sd_flux = std::sqrt(sff / n - mean_flux * mean_flux);
  std::printf("3 stamps: e1 sd %.4e stated %.4e; e2 sd %.4e stated %.4e; S/N measured %.2f stated %.2f\n", sd1, err1,
              sd2, err2, mean_flux / sd_flux, snr);
  // 1,500 realisations measure a standard deviation to ~1.8 %.
  EXPECT_NEAR(err1 / sd1, 1, 0.08);
  EXPECT_NEAR(err2 / sd2, 1, 0.08);
  EXPECT_NEAR(snr / (mean_flux / sd_flux), 1, 0.08);
}

TEST(WeightedMoments, ABadStampIsInvalid) {
  const double c[3] = {0.4, 0.0, 0.4};
  SkyStamp s = sky_stamp(60, 0, 0, c, kJacobians[0], kRefs[0][0], kRefs[0][1], 1.0);
  std::vector<double> scratch;
  MomentsStamp singular = s.stamp;
  singular.dudx = singular.dvdx = 0;  // det J = 0
  EXPECT_FALSE(weighted_moments({&singular, 1}, 1.5, scratch).valid);
  MomentsStamp unscaled = s.stamp;
  unscaled.flux_scale = 0;
  EXPECT_FALSE(weighted_moments({&unscaled, 1}, 1.5, scratch).valid);
  MomentsStamp away = s.stamp;
  away.x_ref = 200;  // the reference lies far outside the stamp: the centroid leaves it
  const MomentsStamp pair[2] = {s.stamp, away};
  EXPECT_FALSE(weighted_moments(pair, 1.5, scratch).valid);
  EXPECT_TRUE(weighted_moments({&s.stamp, 1}, 1.5, scratch).valid);
  EXPECT_FALSE(weighted_moments(std::span<const MomentsStamp>(), 1.5, scratch).valid);
}

}  // namespace
}  // namespace stampede::kernels
