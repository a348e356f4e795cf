// Tests kernels/math/fft_size: the smallest 7-smooth size at least n.
#include "kernels/math/fft_size.hpp"

#include <gtest/gtest.h>

namespace stampede::kernels {
namespace {

bool seven_smooth(int m) {
  for (int f : {2, 3, 5, 7})
    while (m % f == 0) m /= f;
  return m == 1;
}

TEST(FftFriendlySize, KnownSizes) {
  EXPECT_EQ(fft_friendly_size(195), 196);  // 2^2 7^2
  EXPECT_EQ(fft_friendly_size(235), 240);  // 235 = 5 * 47
  EXPECT_EQ(fft_friendly_size(211), 216);  // 211 is prime
  EXPECT_EQ(fft_friendly_size(1), 1);
  EXPECT_EQ(fft_friendly_size(0), 1);
}

TEST(FftFriendlySize, IsTheSmallestSevenSmoothSizeAtLeastN) {
  for (int n = 1; n < 2000; ++n) {
    const int m = fft_friendly_size(n);
    EXPECT_GE(m, n);
    EXPECT_TRUE(seven_smooth(m)) << n;
    for (int k = n; k < m; ++k) EXPECT_FALSE(seven_smooth(k)) << n;
  }
}

}  // namespace
}  // namespace stampede::kernels
