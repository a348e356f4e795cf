// Masked pixels of a cell (kernels/mask_fill): the symmetrised mask holds each masked pixel and
// its three quarter turns, so a mask's quadrupole vanishes; the fill leaves unmasked pixels alone, gives
// a constant its value and a linear ramp its value across a masked column, follows a smooth
// profile into a masked disc, fills several planes as one, and a cell masked whole with zeros.
#include "kernels/mask_fill.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <random>
#include <utility>
#include <vector>

namespace stampede::kernels {
namespace {

TEST(MaskFill, SymmetrisedMaskAddsEachPixelsQuarterTurnsAndCancelsTheQuadrupole) {
  const int side = 9;
  std::vector<std::uint8_t> mask(side * side, 0), turned;
  mask[0 * side + 1] = 1;  // (x 1, y 0) -> (8, 1) -> (7, 8) -> (0, 7)
  symmetrise_mask(mask, side, &turned);
  int count = 0;
  for (std::uint8_t m : mask) count += m;
  EXPECT_EQ(count, 4);
  EXPECT_EQ(mask[1 * side + 8], 1);
  EXPECT_EQ(mask[8 * side + 7], 1);
  EXPECT_EQ(mask[7 * side + 0], 1);
  // A symmetric mask is its own symmetrisation.
  const std::vector<std::uint8_t> once = mask;
  symmetrise_mask(mask, side, &turned);
  EXPECT_EQ(mask, once);
  // An asymmetric mask (a bad column segment and a blob off-centre, not meeting their turns).
  const int big = 31;
  std::vector<std::uint8_t> m(big * big, 0);
  for (int y = 2; y < 12; ++y) m[static_cast<std::size_t>(y) * big + 3] = 1;
  for (int y = 20; y < 24; ++y)
    for (int x = 22; x < 29; ++x) m[static_cast<std::size_t>(y) * big + x] = 1;
  const auto quadrupole = [&](const std::vector<std::uint8_t>& k, int which) {
    double q = 0, c = 0.5 * (big - 1);
    for (int y = 0; y < big; ++y)
      for (int x = 0; x < big; ++x)
        if (k[static_cast<std::size_t>(y) * big + x])
          q += which == 1 ? (x - c) * (x - c) - (y - c) * (y - c) : 2 * (x - c) * (y - c);
    return q;
  };
  EXPECT_NE(quadrupole(m, 1), 0.0);
  symmetrise_mask(m, big, &turned);
  EXPECT_EQ(quadrupole(m, 1), 0.0);
  EXPECT_EQ(quadrupole(m, 2), 0.0);
}

TEST(MaskFill, FillsConstantsRampsAndSmoothProfilesAndLeavesUnmaskedPixels) {
  const int side = 64;
  const std::size_t n = static_cast<std::size_t>(side) * side;
  std::vector<std::uint8_t> mask(n, 0);
  for (int y = 0; y < side; ++y) mask[static_cast<std::size_t>(y) * side + 20] = 1;  // a bad column
  for (int y = 0; y < side; ++y)
    for (int x = 0; x < side; ++x)
      if (std::hypot(x - 44.0, y - 40.0) < 6) mask[static_cast<std::size_t>(y) * side + x] = 1;  // a star's disc
  std::mt19937_64 rng(3);
  std::normal_distribution<double> gauss;
  std::vector<double> constant(n, 2.5), ramp(n), blob(n), noise(n);
  for (int y = 0; y < side; ++y)
    for (int x = 0; x < side; ++x) {
      const std::size_t p = static_cast<std::size_t>(y) * side + x;
      ramp[p] = 1 + 0.3 * x - 0.2 * y;
      blob[p] = 100 * std::exp(-(std::pow(x - 40.0, 2) + std::pow(y - 38.0, 2)) / (2 * 8.0 * 8.0));
      noise[p] = gauss(rng);
    }
  const std::vector<double> ramp0 = ramp, blob0 = blob, noise0 = noise;
  MaskFillScratch scratch;
  std::vector<std::span<double>> planes = {constant, ramp, blob, noise};
  long long masked = 0;
  for (std::uint8_t m : mask) masked += m;
  EXPECT_EQ(fill_masked_pixels(mask, side, planes, &scratch), masked);
  for (std::size_t p = 0; p < n; ++p) {
    EXPECT_NEAR(constant[p], 2.5, 1e-12) << p;
    if (!mask[p]) {
      EXPECT_EQ(ramp[p], ramp0[p]);
      EXPECT_EQ(blob[p], blob0[p]);
      EXPECT_EQ(noise[p], noise0[p]);
    }
  }
  // A ramp exactly, across the column and into the disc alike (the fitted plane is the ramp).
  // The blob (sigma 8 px, peak 100 beside the disc): a plane cannot follow its curvature over the
  // 12 px disc (docs/survey_metadetect.md): within a third of the peak inside, and the disc's rim
  // (masked pixels beside unmasked ones) within 7 % of it.
  for (int y = 0; y < side; ++y)
    for (int x = 0; x < side; ++x) {
      const std::size_t p = static_cast<std::size_t>(y) * side + x;
      if (!mask[p]) continue;
      EXPECT_NEAR(ramp[p], ramp0[p], 1e-9) << x << ", " << y;
      bool rim = false;
      for (const auto& [u, v] : {std::pair{x - 1, y}, std::pair{x + 1, y}, std::pair{x, y - 1}, std::pair{x, y + 1}})
        rim = rim || (u >= 0 && v >= 0 && u < side && v < side && !mask[static_cast<std::size_t>(v) * side + u]);
      if (x < 30) continue;  // the column: the blob is 0.05 of its peak there
      EXPECT_NEAR(blob[p], blob0[p], rim ? 7.0 : 33.0) << x << ", " << y;
    }
  // The noise plane filled by its neighbours' mean: far smaller than the noise (no new noise).
  double filled = 0;
  int k = 0;
  for (std::size_t p = 0; p < n; ++p)
    if (mask[p]) filled += noise[p] * noise[p], ++k;
  EXPECT_LT(std::sqrt(filled / k), 0.7);
  // A plane filled alone is filled as among others.
  std::vector<double> alone = ramp0;
  std::vector<std::span<double>> one = {alone};
  fill_masked_pixels(mask, side, one, &scratch);
  EXPECT_EQ(alone, ramp);
  // Everything masked: zeros.
  std::vector<std::uint8_t> all(n, 1);
  std::vector<double> v(n, 7.0);
  std::vector<std::span<double>> only = {v};
  EXPECT_EQ(fill_masked_pixels(all, side, only, &scratch), static_cast<long long>(n));
  for (double x : v) EXPECT_EQ(x, 0.0);
}


// The fill computes its Gaussian sums at the pixels still to fill only: each must be what a direct
// sum over the whole cell gives (the plane fitted by least squares at the scale the quarter-weight
// rule picks), here on random discs and columns over a random image.
TEST(MaskFill, EachFilledPixelIsTheDirectWeightedPlaneFitAtItsScale) {
  constexpr int kSide = 61;
  const auto n = static_cast<std::size_t>(kSide);
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> u(0, 1);
  std::vector<std::uint8_t> mask(n * n, 0);
  for (int d = 0; d < 3; ++d) {
    const double cx = 60 * u(rng), cy = 60 * u(rng), r = 2 + 8 * u(rng);
    for (std::size_t p = 0; p < n * n; ++p)
      if (std::hypot(static_cast<double>(p % n) - cx, static_cast<double>(p / n) - cy) <= r) mask[p] = 1;
  }
  for (std::size_t y = 0; y < n; ++y) mask[y * n + 40] = 1;
  std::vector<double> image(n * n);
  for (double& v : image) v = u(rng);
  const std::vector<double> original = image;
  MaskFillScratch scratch;
  const std::span<double> planes[1] = {image};
  fill_masked_pixels(mask, kSide, planes, &scratch);
  int checked = 0;
  for (std::size_t p = 0; p < n * n; ++p) {
    if (!mask[p]) {
      ASSERT_EQ(image[p], original[p]);
      continue;
    }
    const double px = static_cast<double>(p % n), py = static_cast<double>(p / n);
    for (double sigma = 1; sigma <= 64; sigma *= 2) {
      // The normalised 1-D Gaussian over the kernel's reach, as the fill's.
      const int half = static_cast<int>(std::ceil(3 * sigma));
      double total = 0;
      for (int d = -half; d <= half; ++d) total += std::exp(-0.5 * d * d / (sigma * sigma));
      double a[3][3] = {}, b[3] = {};
      for (std::size_t q = 0; q < n * n; ++q) {
        const double dx = static_cast<double>(q % n) - px, dy = static_cast<double>(q / n) - py;
        if (mask[q] || std::abs(dx) > half || std::abs(dy) > half) continue;
        const double w = std::exp(-0.5 * (dx * dx + dy * dy) / (sigma * sigma)) / (total * total);
        const double f[3] = {1, dx, dy};
        for (int i = 0; i < 3; ++i) {
          b[i] += w * f[i] * original[q];
          for (int j = 0; j < 3; ++j) a[i][j] += w * f[i] * f[j];
        }
      }
      if (a[0][0] < 0.25) continue;
      // The plane's value at the pixel, a, by Cramer's rule.
      auto det3 = [](const double m[3][3]) {
        return m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1]) - m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0]) +
               m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0]);
      };
      const double det = det3(a);
      double expected = b[0] / a[0][0];
      if (det > 1e-6 * std::pow(a[0][0], 3) * std::pow(sigma, 4)) {
        double a0[3][3] = {{b[0], a[0][1], a[0][2]}, {b[1], a[1][1], a[1][2]}, {b[2], a[2][1], a[2][2]}};
        expected = det3(a0) / det;
      }
      EXPECT_NEAR(image[p], expected, 1e-9) << "pixel " << p % n << ", " << p / n << " at sigma " << sigma;
      ++checked;
      break;
    }
  }
  EXPECT_GT(checked, 200);
}

}  // namespace
}  // namespace stampede::kernels
