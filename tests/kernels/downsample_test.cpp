// Tests kernels/downsample: block averaging against explicit loops, with and without an offset,
// and its invariants (constants stay constant, the sum scales by factor^2).
#include "kernels/downsample.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <vector>

namespace stampede::kernels {
namespace {

std::vector<double> random_image(int size, unsigned seed) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u(-1.0, 3.0);
  std::vector<double> v(static_cast<std::size_t>(size) * size);
  for (double& x : v) x = u(rng);
  return v;
}

// Mean of in[(offset + y f + b) * in_size + offset + x f + a] over a, b < f.
std::vector<double> reference(const std::vector<double>& in, int in_size, int f, int offset, int out_size) {
  std::vector<double> out(static_cast<std::size_t>(out_size) * out_size);
  for (int y = 0; y < out_size; ++y)
    for (int x = 0; x < out_size; ++x) {
      double s = 0.0;
      for (int b = 0; b < f; ++b)
        for (int a = 0; a < f; ++a) s += in[(offset + y * f + b) * in_size + offset + x * f + a];
      out[y * out_size + x] = s / (f * f);
    }
  return out;
}

TEST(BlockAverage, MatchesExplicitLoops) {
  struct Case {
    int in_size, factor, offset, out_size;
  };
  // Offsets that are and are not multiples of the factor, the data stamp inside a padded grid, and
  // factor 1 (a copy of a window).
  for (const Case& c : {Case{20, 3, 2, 6}, Case{25, 5, 0, 5}, Case{35, 5, 5, 5}, Case{16, 2, 1, 7}, Case{12, 1, 3, 9},
                        Case{49, 7, 7, 5}}) {
    const std::vector<double> in = random_image(c.in_size, 17u + c.factor);
    std::vector<double> out(static_cast<std::size_t>(c.out_size) * c.out_size, NAN);  // must be overwritten
    block_average(in.data(), c.in_size, c.factor, c.offset, c.out_size, out.data());
    const std::vector<double> ref = reference(in, c.in_size, c.factor, c.offset, c.out_size);
    // Sums of f^2 <= 49 terms of size <= 3 in a different order: < 50 ulp of 3.
    for (std::size_t k = 0; k < ref.size(); ++k)
      EXPECT_NEAR(out[k], ref[k], 1e-13) << "in " << c.in_size << " f " << c.factor << " off " << c.offset << " k " << k;
  }
}

TEST(BlockAverage, ConstantStaysConstant) {
  const int in_size = 30, f = 5;
  const std::vector<double> in(in_size * in_size, 0.731);
  std::vector<double> out(6 * 6, 0.0);
  block_average(in.data(), in_size, f, 0, 6, out.data());
  for (double v : out) EXPECT_NEAR(v, 0.731, 1e-15);  // 25 additions then one scaling: a few ulp
}

TEST(BlockAverage, ConservesSumTimesFactorSquared) {
  // Without offset and with in_size = out_size * f every input pixel is used exactly once.
  for (int f : {2, 3, 5}) {
    const int out_size = 7, in_size = out_size * f;
    const std::vector<double> in = random_image(in_size, 99u + f);
    std::vector<double> out(out_size * out_size);
    block_average(in.data(), in_size, f, 0, out_size, out.data());
    double s_in = 0.0, s_out = 0.0;
    for (double v : in) s_in += v;
    for (double v : out) s_out += v;
    EXPECT_NEAR(s_out * f * f, s_in, 1e-11 * in.size()) << "f = " << f;  // |values| <= 3, n additions
  }
}

TEST(BlockAverage, OffsetSelectsTheRightBlock) {
  // A single bright sub-pixel must land in exactly one output pixel: the one whose block contains it.
  const int in_size = 23, f = 3, offset = 4, out_size = 6;
  for (int sy : {4, 9, 21}) {
    for (int sx : {4, 10, 12, 21}) {
      std::vector<double> in(in_size * in_size, 0.0);
      in[sy * in_size + sx] = 9.0;
      std::vector<double> out(out_size * out_size, 0.0);
      block_average(in.data(), in_size, f, offset, out_size, out.data());
      const int ox = (sx - offset) / f, oy = (sy - offset) / f;
      for (int y = 0; y < out_size; ++y)
        for (int x = 0; x < out_size; ++x)
          EXPECT_EQ(out[y * out_size + x], (x == ox && y == oy) ? 1.0 : 0.0) << "sub-pixel (" << sx << ", " << sy << ")";
    }
  }
  // Sub-pixels before the offset are never read.
  std::vector<double> in(in_size * in_size, 0.0);
  for (int k = 0; k < in_size; ++k) in[k] = in[k * in_size] = in[3 * in_size + k] = in[k * in_size + 3] = 1e9;
  std::vector<double> out(out_size * out_size, 1.0);
  block_average(in.data(), in_size, f, offset, out_size, out.data());
  for (double v : out) EXPECT_EQ(v, 0.0);
}

}  // namespace
}  // namespace stampede::kernels
