// Tests kernels/prepsf_moments: an elliptical Gaussian galaxy seen through a Gaussian PSF, anywhere
// in the stamp, gives its pre-PSF moments under the weight (analytic: the weighted covariance is
// (C^-1 + W^-1)^-1, whatever the PSF); the stated errors and S/N match the scatter over noise
// realisations; a PSF transform that vanishes where the weight needs it, or no flux, is invalid.
#include "kernels/prepsf_moments.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <numbers>
#include <random>
#include <vector>

namespace stampede::kernels {
namespace {

struct Cov {
  double xx, xy, yy;
};

// Point-sampled at pixel centres (sigma >= 2 px: aliasing far below the tolerances).
std::vector<double> gaussian(int n, double x0, double y0, Cov c, double flux) {
  const double det = c.xx * c.yy - c.xy * c.xy;
  const double ixx = c.yy / det, iyy = c.xx / det, ixy = -c.xy / det;
  std::vector<double> img(static_cast<std::size_t>(n) * n);
  for (int j = 0; j < n; ++j)
    for (int i = 0; i < n; ++i) {
      const double dx = i - x0, dy = j - y0;
      img[j * n + i] = flux / (2 * std::numbers::pi * std::sqrt(det)) *
                       std::exp(-0.5 * (ixx * dx * dx + 2 * ixy * dx * dy + iyy * dy * dy));
    }
  return img;
}

// The Gaussian PSF's transform exp(-k^T P k / 2) on the stamp's DFT grid.
std::vector<double> gaussian_k(int n, Cov p) {
  std::vector<double> out(static_cast<std::size_t>(n) * n);
  for (int j = 0; j < n; ++j)
    for (int i = 0; i < n; ++i) {
      const double kx = dft_frequency(i, n), ky = dft_frequency(j, n);
      out[j * n + i] = std::exp(-0.5 * (p.xx * kx * kx + 2 * p.xy * kx * ky + p.yy * ky * ky));
    }
  return out;
}

TEST(PrepsfMoments, AGaussianThroughAnyGaussianPsfGivesItsPrePsfWeightedMoments) {
  const double fwhm = 8.0, w = std::pow(fwhm / 2.3548200450309493, 2);
  const Cov c{6.0, 1.5, 4.0};  // the galaxy before its PSF, pixels^2
  const double flux = 100;
  // Expected: Q = (C^-1 + I / w)^-1, flux integral w G = F sqrt(det Q / det C).
  const double det = c.xx * c.yy - c.xy * c.xy;
  const double axx = c.yy / det + 1 / w, ayy = c.xx / det + 1 / w, axy = -c.xy / det;
  const double adet = axx * ayy - axy * axy;
  const double qxx = ayy / adet, qyy = axx / adet, qxy = -axy / adet;
  const double t = qxx + qyy, e1 = (qxx - qyy) / t, e2 = 2 * qxy / t;
  const double f = flux * std::sqrt((qxx * qyy - qxy * qxy) / det);
  std::vector<std::complex<double>> scratch;
  for (int n : {49, 48}) {
    for (const Cov& p : {Cov{4.0, 0.0, 4.0}, Cov{7.0, -1.2, 5.0}}) {
      const std::vector<double> psf_k = gaussian_k(n, p);
      for (double offset : {0.0, 0.37, -1.8}) {
        const double x0 = 0.5 * (n - 1) + offset, y0 = 0.5 * (n - 1) - 0.6 * offset;
        const std::vector<double> img = gaussian(n, x0, y0, {c.xx + p.xx, c.xy + p.xy, c.yy + p.yy}, flux);
        const PrepsfMoments m = prepsf_moments(img, n, x0, y0, fwhm, psf_k, 0.0, scratch);
        ASSERT_TRUE(m.valid);
        EXPECT_NEAR(m.e1, e1, 1e-6) << n << " " << offset;
        EXPECT_NEAR(m.e2, e2, 1e-6) << n << " " << offset;
        EXPECT_NEAR(m.t / t, 1, 1e-6) << n << " " << offset;
        EXPECT_NEAR(m.flux / f, 1, 1e-6) << n << " " << offset;
      }
    }
  }
  // The pre-PSF shape is not the observed one: wmom of the same image would see C + P.
  EXPECT_GT(std::abs(e1), 0.05);
}

TEST(PrepsfMoments, StatedErrorsMatchTheScatterOverNoise) {
  const int n = 41;
  const double fwhm = 7.0, sigma_n = 0.02;
  const Cov p{3.0, 0.0, 3.0};
  const std::vector<double> psf_k = gaussian_k(n, p);
  const std::vector<double> clean = gaussian(n, 20, 20, {5.0 + p.xx, 1.0, 3.5 + p.yy}, 50);
  std::mt19937_64 rng(7);
  std::normal_distribution<double> normal(0, sigma_n);
  std::vector<std::complex<double>> scratch;
  std::vector<double> img(clean.size());
  const int draws = 600;
  double s1 = 0, s11 = 0, s2 = 0, s22 = 0, sf = 0, sff = 0, err1 = 0, err2 = 0, snr = 0;
  for (int d = 0; d < draws; ++d) {
    for (std::size_t q = 0; q < img.size(); ++q) img[q] = clean[q] + normal(rng);
    const PrepsfMoments m = prepsf_moments(img, n, 20, 20, fwhm, psf_k, sigma_n * sigma_n, scratch);
    ASSERT_TRUE(m.valid);
    s1 += m.e1, s11 += m.e1 * m.e1, s2 += m.e2, s22 += m.e2 * m.e2, sf += m.flux, sff += m.flux * m.flux;
    err1 += m.e1_err, err2 += m.e2_err, snr += m.snr;
  }
  auto sd = [&](double s, double ss) { return std::sqrt(ss / draws - (s / draws) * (s / draws)); };
  // 600 draws: the sample standard deviation is good to ~3 %.
  EXPECT_NEAR(sd(s1, s11) / (err1 / draws), 1, 0.1);
  EXPECT_NEAR(sd(s2, s22) / (err2 / draws), 1, 0.1);
  EXPECT_NEAR(sd(sf, sff) / ((sf / draws) / (snr / draws)), 1, 0.1);
  EXPECT_GT(snr / draws, 5);  // a measurement, not noise
}

TEST(PrepsfMoments, NoFluxOrAVanishingPsfIsInvalid) {
  const int n = 33;
  std::vector<std::complex<double>> scratch;
  std::vector<double> psf_k = gaussian_k(n, {3.0, 0.0, 3.0});
  const std::vector<double> zero(static_cast<std::size_t>(n) * n, 0.0);
  EXPECT_FALSE(prepsf_moments(zero, n, 16, 16, 6.0, psf_k, 1.0, scratch).valid);
  const std::vector<double> img = gaussian(n, 16, 16, {6.0, 0.0, 6.0}, 10);
  EXPECT_TRUE(prepsf_moments(img, n, 16, 16, 6.0, psf_k, 0.0, scratch).valid);
  psf_k[3] = 0;  // at k = 3 (2 pi / 33): the weight is far from negligible there
  EXPECT_FALSE(prepsf_moments(img, n, 16, 16, 6.0, psf_k, 0.0, scratch).valid);
  EXPECT_FALSE(prepsf_moments(img, n, 16, 16, 6.0, std::span<const double>(psf_k).first(10), 0.0, scratch).valid);
}

}  // namespace
}  // namespace stampede::kernels
