// Tests for the metacalibrated set shear (engine/analysis/metacal_shear): the response matrix
// inverted, ring pairs averaged, and the selection response from the sheared selections.
#include "engine/analysis/metacal_shear.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <vector>

namespace stampede {
namespace {

// Ring pairs sheared by g with a known response R: e = R g + shape noise (cancelling in pairs).
// With every object selected, g = <R>^-1 <e> exactly, off-diagonal terms included.
TEST(MetacalShear, RingPairsWithAKnownResponseGiveTheShearBack) {
  const double g1 = 0.03, g2 = -0.02;
  const double r[4] = {0.8, 0.05, -0.03, 0.9};
  std::vector<double> e1, e2, r11, r12, r21, r22;
  std::vector<long long> pair;
  std::vector<std::uint8_t> sel;
  for (int p = 0; p < 50; ++p) {
    const double s1 = 0.3 * std::sin(p), s2 = 0.2 * std::cos(3 * p);
    for (int m = 0; m < 2; ++m) {
      const double sign = m ? -1 : 1;
      e1.push_back(r[0] * g1 + r[1] * g2 + sign * s1);
      e2.push_back(r[2] * g1 + r[3] * g2 + sign * s2);
      r11.push_back(r[0] + 0.1 * sign * s1), r12.push_back(r[1]), r21.push_back(r[2]), r22.push_back(r[3] - 0.1 * sign * s2);
      pair.push_back(p);
      sel.push_back(0x1f);
    }
  }
  MetacalRows rows{e1, e2, {r11, r12, r21, r22}, sel, pair, 0.01};
  const MetacalSetShear s = estimate_metacal_set_shear(rows, g1, g2, 100, 7);
  EXPECT_NEAR(s.shear.g1, g1, 1e-15);
  EXPECT_NEAR(s.shear.g2, g2, 1e-15);
  EXPECT_NEAR(s.r[0], 0.8, 1e-15);
  EXPECT_EQ(s.r_sel[0], 0.0);
  EXPECT_EQ(s.shear.used, 100);
  EXPECT_LT(s.shear.err1, 1e-8);  // no scatter between pairs (the floor of sum-of-squares variance: ~1e-9)
}

// The selection response: objects whose 1p-image quantities pass a cut the 1m ones fail shift
// <e1> between the two selections; R_S11 = (<e1>_S(1p) - <e1>_S(1m)) / 2 step.
TEST(MetacalShear, TheSelectionResponseComesFromTheShearedSelections) {
  // Four lone objects; R = identity. Object 3 passes on noshear and 1p only.
  const std::vector<double> e1 = {0.1, -0.1, 0.2, 0.4}, e2 = {0, 0, 0, 0};
  const std::vector<double> one(4, 1.0), zero(4, 0.0);
  const std::vector<std::uint8_t> sel = {0x1f, 0x1f, 0x1f, 0x1 | 0x2};
  MetacalRows rows{e1, e2, {one, zero, zero, one}, sel, {}, 0.01};
  const MetacalSetShear s = estimate_metacal_set_shear(rows, 0, 0, 0, 1);
  const double with = (0.1 - 0.1 + 0.2 + 0.4) / 4, without = (0.1 - 0.1 + 0.2) / 3;
  EXPECT_NEAR(s.r_sel[0], (with - without) / 0.02, 1e-12);
  EXPECT_NEAR(s.r_sel[1], (without - without) / 0.02, 1e-12);  // 2p and 2m both drop object 3
  EXPECT_NEAR(s.shear.g1, with / (1 + s.r_sel[0]), 1e-12);
  EXPECT_EQ(s.shear.used, 4);
}

// An object whose e or R is not finite leaves every selection with its pair.
TEST(MetacalShear, ANonFiniteRowDropsItsPair) {
  const std::vector<double> e1 = {0.1, -0.1, 0.3, NAN}, e2(4, 0.0), one(4, 1.0), zero(4, 0.0);
  const std::vector<std::uint8_t> sel(4, 0x1f);
  const std::vector<long long> pair = {0, 0, 1, 1};
  MetacalRows rows{e1, e2, {one, zero, zero, one}, sel, pair, 0.01};
  const MetacalSetShear s = estimate_metacal_set_shear(rows, 0, 0, 0, 1);
  EXPECT_EQ(s.shear.used, 2);
  EXPECT_EQ(s.shear.excluded, 2);
  EXPECT_NEAR(s.shear.g1, 0.0, 1e-15);
}

// A cut that no unit passes on one sheared image leaves <e> over that selection, R_S and g
// undefined: NaN (never a zero <R>), with the empty selection named by its units' count.
TEST(MetacalShear, AnEmptyShearedSelectionIsNamedAndGivesNaN) {
  const std::vector<double> e1 = {0.1, -0.1, 0.2, -0.2}, e2(4, 0.0), one(4, 1.0), zero(4, 0.0);
  const std::vector<std::uint8_t> sel(4, 0x1f & ~0x4);  // every object fails on the 1m image
  const std::vector<long long> pair = {0, 0, 1, 1};
  MetacalRows rows{e1, e2, {one, zero, zero, one}, sel, pair, 0.01};
  const MetacalSetShear s = estimate_metacal_set_shear(rows, 0, 0, 100, 1);
  EXPECT_EQ(s.empty_selection(), 2);
  EXPECT_STREQ(kMetacalSelectionNames[s.empty_selection()], "1m");
  EXPECT_EQ(s.selected_units, (std::array<long long, 5>{2, 2, 0, 2, 2}));
  EXPECT_TRUE(std::isnan(s.shear.g1) && std::isnan(s.r[0]) && std::isnan(s.r_sel[0])) << s.r[0];
  EXPECT_TRUE(std::isnan(s.shear.err1));
}

// One selected ring pair: no bootstrap error (NaN), not 0.
TEST(MetacalShear, OneSelectedRingPairHasNoError) {
  const std::vector<double> e1 = {0.1, -0.1, 0.2, -0.2}, e2(4, 0.0), one(4, 1.0), zero(4, 0.0);
  const std::vector<std::uint8_t> sel = {0x1f, 0x1f, 0, 0x1f};
  const std::vector<long long> pair = {0, 0, 1, 1};
  MetacalRows rows{e1, e2, {one, zero, zero, one}, sel, pair, 0.01};
  const MetacalSetShear s = estimate_metacal_set_shear(rows, 0, 0, 100, 1);
  EXPECT_EQ(s.shear.units, 1);
  EXPECT_NEAR(s.shear.g1, 0.0, 1e-15);
  EXPECT_TRUE(std::isnan(s.shear.err1) && std::isnan(s.shear.err2)) << s.shear.err1;
  EXPECT_EQ(s.empty_selection(), -1);
}

}  // namespace
}  // namespace stampede
