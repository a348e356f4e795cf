// Tests kernels/moments: adaptive moments recover a known elliptical Gaussian's centroid and
// covariance, ignore masked pixels, reject images without positive flux; covariance_ellipticity
// returns (a-b)/(a+b) along the position angle.
#include "kernels/moments.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <numbers>
#include <vector>

namespace stampede::kernels {
namespace {

struct Gaussian {
  double x0, y0;         // centre, pixels
  double a, b, theta;    // sigma along the major / minor axis, position angle
  double flux;
  double cxx() const { return a * a * std::cos(theta) * std::cos(theta) + b * b * std::sin(theta) * std::sin(theta); }
  double cyy() const { return a * a * std::sin(theta) * std::sin(theta) + b * b * std::cos(theta) * std::cos(theta); }
  double cxy() const { return (a * a - b * b) * std::sin(theta) * std::cos(theta); }
};

// Point-sampled at pixel centres. With sigma >= 2 px the sampled Gaussian's (weighted) moments equal
// the continuous ones up to Poisson-summation aliasing terms ~exp(-2 pi^2 sigma^2) < 1e-30, so no
// pixel-window (1/12 px^2) correction applies: that term belongs to pixel-integrated images.
std::vector<double> render(const Gaussian& g, int size) {
  const double det = g.cxx() * g.cyy() - g.cxy() * g.cxy();
  const double ixx = g.cyy() / det, iyy = g.cxx() / det, ixy = -g.cxy() / det;
  const double norm = g.flux / (2 * std::numbers::pi * std::sqrt(det));
  std::vector<double> img(static_cast<std::size_t>(size) * size);
  for (int j = 0; j < size; ++j)
    for (int i = 0; i < size; ++i) {
      const double dx = i - g.x0, dy = j - g.y0;
      img[j * size + i] = norm * std::exp(-0.5 * (ixx * dx * dx + 2 * ixy * dx * dy + iyy * dy * dy));
    }
  return img;
}

// The iteration stops when the covariance changes by < 1e-6 (xx + yy) and the centroid by < 1e-6 px
// per step; the fixed-point map contracts errors by 1/2 per step for a Gaussian, so the residual is
// of the same order. 2e-5 px and 2e-5 relative (with 2e-5 (xx+yy) floor for the cross term) leave a
// factor ~10 margin and are 50x tighter than the 1e-3 the fitter needs from a starting point.
constexpr double kCentroidTol = 2e-5;
constexpr double kCovTol = 2e-5;

void expect_recovers(const Gaussian& g, const ImageMoments& m) {
  ASSERT_TRUE(m.valid);
  EXPECT_NEAR(m.x, g.x0, kCentroidTol);
  EXPECT_NEAR(m.y, g.y0, kCentroidTol);
  const double trace = g.cxx() + g.cyy();
  EXPECT_NEAR(m.xx, g.cxx(), kCovTol * g.cxx());
  EXPECT_NEAR(m.yy, g.cyy(), kCovTol * g.cyy());
  EXPECT_NEAR(m.xy, g.cxy(), kCovTol * trace);
}

TEST(AdaptiveMoments, RecoverEllipticalGaussian) {
  const int size = 48;
  for (const Gaussian& g : {Gaussian{23.3, 24.62, 3.0, 2.0, 0.4, 1000.0}, Gaussian{21.85, 22.1, 4.0, 2.2, -1.2, 5.0},
                            Gaussian{24.0, 23.5, 2.5, 2.5, 0.0, 1.0}, Gaussian{22.51, 25.07, 3.5, 2.0, 2.0, 300.0}}) {
    const std::vector<double> img = render(g, size);
    const std::vector<double> ones(img.size(), 1.0);
    const ImageMoments m = adaptive_moments(img, ones, size);
    expect_recovers(g, m);
    // Unweighted flux: the sampled Gaussian sums to its flux.
    EXPECT_NEAR(m.flux, g.flux, 1e-5 * g.flux);  // > 5.4 sigma to every edge: lost flux < 1e-6
    EXPECT_GT(m.iterations, 1);
    // Shape: the contours' semi-axes are proportional to (sigma_a, sigma_b), so the ellipticity of
    // the measured covariance is (a-b)/(a+b) in sigmas; 1e-4 follows from the covariance tolerance.
    double e1 = 0, e2 = 0;
    covariance_ellipticity(m.xx, m.xy, m.yy, &e1, &e2);
    const double e = (g.a - g.b) / (g.a + g.b);
    EXPECT_NEAR(e1, e * std::cos(2 * g.theta), 1e-4);
    EXPECT_NEAR(e2, e * std::sin(2 * g.theta), 1e-4);
  }
}

TEST(AdaptiveMoments, MaskedPixelsAreIgnored) {
  const int size = 40;
  const Gaussian g{19.4, 20.2, 3.0, 2.4, 0.9, 100.0};
  std::vector<double> clean = render(g, size);
  std::vector<double> mask(clean.size(), 1.0);
  // A masked cosmic ray near the core, a masked bad column, a masked NaN.
  for (int j = 0; j < size; ++j) mask[j * size + 5] = 0.0;
  mask[21 * size + 18] = 0.0;
  mask[10 * size + 30] = 0.0;
  std::vector<double> dirty = clean;
  for (int j = 0; j < size; ++j) dirty[j * size + 5] = -5e3;
  dirty[21 * size + 18] = 1e6;
  dirty[10 * size + 30] = NAN;
  const ImageMoments a = adaptive_moments(clean, mask, size);
  const ImageMoments b = adaptive_moments(dirty, mask, size);
  ASSERT_TRUE(a.valid);
  ASSERT_TRUE(b.valid);
  // Identical arithmetic on the unmasked pixels: bitwise equal.
  EXPECT_EQ(a.x, b.x);
  EXPECT_EQ(a.y, b.y);
  EXPECT_EQ(a.xx, b.xx);
  EXPECT_EQ(a.xy, b.xy);
  EXPECT_EQ(a.yy, b.yy);
  EXPECT_EQ(a.flux, b.flux);
  // The mask matters: masking one core pixel (~2% of the weighted flux, 1.6 px off-centre) moves the
  // centroid by a few hundredths of a pixel, and without the mask the garbage pixels ruin it.
  const ImageMoments unmasked_clean = adaptive_moments(clean, std::vector<double>(clean.size(), 1.0), size);
  EXPECT_GT(std::abs(unmasked_clean.x - b.x) + std::abs(unmasked_clean.y - b.y), 1e-2);
  const ImageMoments unmasked_dirty = adaptive_moments(dirty, std::vector<double>(clean.size(), 1.0), size);
  EXPECT_TRUE(!unmasked_dirty.valid || std::abs(unmasked_dirty.x - g.x0) > 0.1);
  // And the flux is the sum over unmasked pixels only.
  double unmasked = 0.0;
  for (std::size_t k = 0; k < clean.size(); ++k)
    if (mask[k] != 0.0) unmasked += clean[k];
  EXPECT_NEAR(b.flux, unmasked, 1e-12 * unmasked);
}

TEST(AdaptiveMoments, NoPositiveFluxIsInvalid) {
  const int size = 20;
  const std::vector<double> ones(size * size, 1.0);
  const std::vector<double> zeros(size * size, 0.0);
  EXPECT_FALSE(adaptive_moments(zeros, ones, size).valid);
  const std::vector<double> negative(size * size, -3.0);
  const ImageMoments neg = adaptive_moments(negative, ones, size);
  EXPECT_FALSE(neg.valid);
  EXPECT_NEAR(neg.flux, -3.0 * size * size, 1e-9);
  // Everything masked: nothing to measure.
  const std::vector<double> img = render(Gaussian{10, 10, 2.5, 2.5, 0, 1}, size);
  EXPECT_FALSE(adaptive_moments(img, zeros, size).valid);
  // A negated Gaussian has no positive pixels at all.
  std::vector<double> flipped = img;
  for (double& v : flipped) v = -v;
  EXPECT_FALSE(adaptive_moments(flipped, ones, size).valid);
}

TEST(CovarianceEllipticity, ReducedShearOfKnownAxes) {
  // Covariance R diag(a^2, b^2) R^T of a Gaussian with sigmas a >= b along theta:
  // e = (a - b) / (a + b) (cos 2 theta, sin 2 theta). Closed form, 1e-14.
  for (double a : {1.0, 2.0, 5.0}) {
    for (double ratio : {1.0, 0.9, 0.5, 0.1}) {
      for (double theta : {0.0, 0.3, 1.2, -0.7, 2.9}) {
        const Gaussian g{0, 0, a, a * ratio, theta, 1};
        double e1 = 0, e2 = 0;
        covariance_ellipticity(g.cxx(), g.cxy(), g.cyy(), &e1, &e2);
        const double e = (1 - ratio) / (1 + ratio);
        EXPECT_NEAR(e1, e * std::cos(2 * theta), 1e-14) << "a " << a << " ratio " << ratio << " theta " << theta;
        EXPECT_NEAR(e2, e * std::sin(2 * theta), 1e-14) << "a " << a << " ratio " << ratio << " theta " << theta;
      }
    }
  }
}

}  // namespace
}  // namespace stampede::kernels
