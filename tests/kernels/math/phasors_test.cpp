// Tests for kernels/math/phasors: the rotated phasors equal exp(i (a + j d)) to rounding over the
// lengths and angles the PSF transforms and metacal's DFT weights use, and every 8th is exact.
#include "kernels/math/phasors.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <complex>
#include <numbers>
#include <vector>

namespace stampede::kernels {
namespace {

TEST(Phasors, EqualTheExponentialToRoundingAndEveryEighthExactly) {
  const double pi = std::numbers::pi;
  for (int n : {1, 7, 25, 49, 97})
    for (double a : {0.0, -1.3, 7.9})
      for (double d : {0.0, 1e-3, -0.37, 2 * pi * 23.4 / 96, -pi}) {
        std::vector<std::complex<double>> got(n);
        phasors(a, d, n, got.data());
        for (int j = 0; j < n; ++j) {
          const std::complex<double> want = std::polar(1.0, a + j * d);
          if (j % 8 == 0)
            EXPECT_EQ(got[j], want) << n << " " << a << " " << d << " " << j;
          else
            // Seven rotations' rounding, and the angles': a + j d rounded to a double (the
            // anchor's and the reference's) differs by up to an ulp of it (~300 rad here).
            EXPECT_LE(std::abs(got[j] - want), 4e-15 + 4.5e-16 * std::abs(a + j * d))
                << n << " " << a << " " << d << " " << j;
        }
      }
}

}  // namespace
}  // namespace stampede::kernels
