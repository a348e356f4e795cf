// Counter-based random streams (engine/common/random_stream): a field of normals by the polar
// method has a standard normal's moments and tail fractions, is the same field for the same keys
// whatever its length's parity, and differs between keys.
#include "engine/common/random_stream.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <vector>

namespace stampede {
namespace {

TEST(RandomStream, NormalsHaveAStandardNormalsMomentsAndTails) {
  constexpr std::size_t kN = 400000;
  std::vector<double> v(kN);
  RandomStream({3, 1, 4}).normals(v);
  double m1 = 0, m2 = 0, m3 = 0, m4 = 0;
  std::size_t beyond2 = 0, beyond3 = 0;
  for (double x : v) {
    m1 += x, m2 += x * x, m3 += x * x * x, m4 += x * x * x * x;
    beyond2 += std::abs(x) > 2, beyond3 += std::abs(x) > 3;
  }
  m1 /= kN, m2 /= kN, m3 /= kN, m4 /= kN;
  // Five standard errors of each estimate (1/sqrt(N), sqrt(2/N), sqrt(15/N), sqrt(96/N)).
  EXPECT_NEAR(m1, 0.0, 5 * std::sqrt(1.0 / kN));
  EXPECT_NEAR(m2, 1.0, 5 * std::sqrt(2.0 / kN));
  EXPECT_NEAR(m3, 0.0, 5 * std::sqrt(15.0 / kN));
  EXPECT_NEAR(m4, 3.0, 5 * std::sqrt(96.0 / kN));
  const double p2 = 0.0455003, p3 = 0.0026998;  // P(|x| > 2), P(|x| > 3)
  EXPECT_NEAR(static_cast<double>(beyond2) / kN, p2, 5 * std::sqrt(p2 * (1 - p2) / kN));
  EXPECT_NEAR(static_cast<double>(beyond3) / kN, p3, 5 * std::sqrt(p3 * (1 - p3) / kN));
}

TEST(RandomStream, NormalsAreKeyedAndAShorterFieldIsThePrefix) {
  std::vector<double> a(1001), b(1000), c(1001);
  RandomStream({7, 2}).normals(a);
  RandomStream({7, 2}).normals(b);
  RandomStream({7, 3}).normals(c);
  EXPECT_TRUE(std::equal(b.begin(), b.end(), a.begin()));
  EXPECT_NE(a, c);
  std::vector<double> again(1001);
  RandomStream({7, 2}).normals(again);
  EXPECT_EQ(a, again);
}

}  // namespace
}  // namespace stampede
