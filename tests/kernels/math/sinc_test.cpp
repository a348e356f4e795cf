// Tests kernels/math/sinc: 1 at 0, exactly 1 through the small-x branch, sin(x) / x elsewhere.
#include "kernels/math/sinc.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <numbers>

namespace stampede::kernels {
namespace {

TEST(Sinc, IsOneAtZero) {
  EXPECT_EQ(sinc(0.0), 1.0);
  EXPECT_EQ(sinc(-0.0), 1.0);
}

TEST(Sinc, SmallArgumentsRoundToOneOnBothSidesOfTheBranch) {
  // Both former definitions (1 below 1e-12; 1 - x^2/6 below 1e-8) and sin(x)/x agree here: the
  // x^2/6 term is under half an ulp of 1 up to ~1.8e-8, so the branch threshold changes nothing.
  for (double x = 1e-300; x < 1.5e-8; x *= 1.7) {
    EXPECT_EQ(sinc(x), 1.0) << x;
    EXPECT_EQ(sinc(-x), 1.0) << x;
    EXPECT_EQ(std::sin(x) / x, 1.0) << x;
    EXPECT_EQ(1.0 - x * x / 6, 1.0) << x;
  }
}

TEST(Sinc, NearZeroFollowsTheTaylorSeries) {
  for (double x : {1e-6, 1e-4, 1e-3, 1e-2}) EXPECT_NEAR(sinc(x), 1 - x * x / 6 + x * x * x * x / 120, 1e-15) << x;
}

TEST(Sinc, LargeArgumentsAreSinOverX) {
  for (double x = 1e-8; x < 1e4; x *= 1.37) {
    EXPECT_EQ(sinc(x), std::sin(x) / x) << x;
    EXPECT_EQ(sinc(-x), sinc(x)) << x;
  }
  for (int k = 1; k < 10; ++k) EXPECT_NEAR(sinc(k * std::numbers::pi), 0.0, 1e-15) << k;
  EXPECT_DOUBLE_EQ(sinc(std::numbers::pi / 2), 2 / std::numbers::pi);
}

}  // namespace
}  // namespace stampede::kernels
