// Tests for shear-pair estimates (engine/analysis/shear_pairs): what the + and - sets share
// cancels in half their difference, whatever its size, so m comes back exactly where independent
// sets would leave it buried in noise; c from half the sum; the units must match.
#include "engine/analysis/shear_pairs.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <vector>

#include "engine/analysis/metacal_shear.hpp"
#include "engine/common/random_stream.hpp"

namespace stampede {
namespace {

// Ring pairs whose noise is the same in both sets: e = (1 + m) g + c + noise, noise ~ 0.3.
struct PairRows {
  std::vector<double> e1, e2;
  std::vector<int> usable;
  std::vector<long long> pair;
};

PairRows rows(double g1, double g2, double m, double c1, double c2, int pairs, std::uint64_t seed) {
  PairRows r;
  std::uint64_t state = seed;
  auto noise = [&] { return 0.3 * (static_cast<double>(splitmix64(state) >> 11) * 0x1.0p-53 - 0.5); };
  for (int p = 0; p < pairs; ++p) {
    const double s1 = noise(), s2 = noise();
    for (int member = 0; member < 2; ++member) {
      const double sign = member ? -1 : 1;
      r.e1.push_back((1 + m) * g1 + c1 + sign * s1 + noise());
      r.e2.push_back((1 + m) * g2 + c2 + sign * s2 + noise());
      r.usable.push_back(1);
      r.pair.push_back(p);
    }
  }
  return r;
}

TEST(ShearPairs, SharedNoiseCancelsInTheHalfDifference) {
  const double m = 0.02, c1 = 3e-4, c2 = -2e-4;
  std::vector<ShearPairEstimate> pairs;
  std::vector<SetShear> independent;
  const double shears[3][2] = {{0.03, -0.01}, {-0.02, 0.04}, {0.045, 0.02}};
  for (int k = 0; k < 3; ++k) {
    const double g1 = shears[k][0], g2 = shears[k][1];
    const PairRows plus = rows(g1, g2, m, c1, c2, 500, 11 + k), minus = rows(-g1, -g2, m, c1, c2, 500, 11 + k);
    const auto up = make_shear_units(plus.e1, plus.e2, plus.usable, plus.pair);
    const auto um = make_shear_units(minus.e1, minus.e2, minus.usable, minus.pair);
    pairs.push_back(estimate_shear_pair(*up, *um, g1, g2, 50, 3));
    EXPECT_NEAR(pairs.back().half_difference[0], (1 + m) * g1, 1e-15);
    EXPECT_NEAR(pairs.back().half_sum[1], c2, 4 * pairs.back().half_sum_err[1]);  // c plus the noise's mean
    EXPECT_LT(pairs.back().half_difference_err[0], 1e-8);  // zero but for the sum-of-squares variance floor
    EXPECT_GT(pairs.back().half_sum_err[0], 1e-4);
    independent.push_back(estimate_set_shear(plus.e1, plus.e2, plus.usable, plus.pair, g1, g2, 50, 3));
    EXPECT_GT(independent.back().err1, 1e-3);  // one set alone carries the noise
  }
  const ShearPairMetrics pm = combine_shear_pairs(pairs, 0, 0);
  EXPECT_NEAR(pm.component[0].m, m, 1e-12);
  EXPECT_NEAR(pm.component[1].m, m, 1e-12);
  // c: the weighted mean of the half sums, where the shared noise does not cancel.
  EXPECT_NEAR(pm.component[0].c, c1, 4 * pm.component[0].c_err);
  EXPECT_GT(pm.component[0].c_err, 1e-3);
  EXPECT_EQ(pm.c_plus, pm.component[0].c);
}

TEST(ShearPairs, MetacalUnitsPairToo) {
  // e = R g + noise with a per-object response: (<e>_+ - <e>_-) / 2 / <R> = g exactly.
  const double g1 = 0.02, g2 = -0.035;
  std::vector<double> ep1, ep2, em1, em2, r11, r12, r21, r22;
  std::vector<long long> pair;
  std::vector<std::uint8_t> sel;
  std::uint64_t state = 5;
  for (int i = 0; i < 400; ++i) {
    const double u = static_cast<double>(splitmix64(state) >> 11) * 0x1.0p-53, n1 = 0.2 * (u - 0.5), n2 = 0.1 * u;
    const double r = 0.6 + 0.4 * u;
    r11.push_back(r), r12.push_back(0), r21.push_back(0), r22.push_back(r);
    ep1.push_back(r * g1 + n1), ep2.push_back(r * g2 + n2);
    em1.push_back(-r * g1 + n1), em2.push_back(-r * g2 + n2);
    pair.push_back(i / 2);
    sel.push_back(0x1f);
  }
  const auto plus = make_metacal_units({ep1, ep2, {r11, r12, r21, r22}, sel, pair, 0.01});
  const auto minus = make_metacal_units({em1, em2, {r11, r12, r21, r22}, sel, pair, 0.01});
  const ShearPairEstimate p = estimate_shear_pair(*plus, *minus, g1, g2, 30, 9);
  EXPECT_NEAR(p.half_difference[0], g1, 1e-15);
  EXPECT_NEAR(p.half_difference[1], g2, 1e-15);
  EXPECT_LT(p.half_difference_err[1], 1e-8);
}

TEST(ShearPairs, SetsOfDifferentObjectsAreRefused) {
  const PairRows a = rows(0.01, 0, 0, 0, 0, 10, 1), b = rows(-0.01, 0, 0, 0, 0, 11, 1);
  const auto ua = make_shear_units(a.e1, a.e2, a.usable, a.pair), ub = make_shear_units(b.e1, b.e2, b.usable, b.pair);
  EXPECT_THROW(estimate_shear_pair(*ua, *ub, 0.01, 0, 10, 1), std::invalid_argument);
}

// Errors: weighted by the bootstrap errors; without them, from the scatter about the line.
TEST(ShearPairs, CombineFitsALineThroughZero) {
  std::vector<ShearPairEstimate> pairs(3);
  const double g[3] = {0.01, 0.02, -0.03}, d[3] = {0.0101, 0.0199, -0.0303};
  for (int k = 0; k < 3; ++k) {
    pairs[k].g1_true = g[k];
    pairs[k].g2_true = g[k];
    pairs[k].half_difference = {d[k], d[k]};
    pairs[k].half_sum = {1e-4 * k, 0};
    pairs[k].half_difference_err = {1e-4, 0};  // component 2 unweighted
    pairs[k].half_sum_err = {1e-4, 0};
  }
  const ShearPairMetrics pm = combine_shear_pairs(pairs, 0, 0.05);
  double sxy = 0, sxx = 0;
  for (int k = 0; k < 3; ++k) sxy += g[k] * d[k], sxx += g[k] * g[k];
  EXPECT_NEAR(pm.component[0].m, sxy / sxx - 1, 1e-14);
  EXPECT_NEAR(pm.component[0].m_err, 1e-4 / std::sqrt(sxx), 1e-14);
  EXPECT_NEAR(pm.component[0].c, 1e-4, 1e-15);
  EXPECT_NEAR(pm.component[0].c_err, 1e-4 / std::sqrt(3.0), 1e-15);
  EXPECT_NEAR(pm.component[1].m, pm.component[0].m, 1e-14);
  double chi2 = 0;
  for (int k = 0; k < 3; ++k) chi2 += std::pow(d[k] - sxy / sxx * g[k], 2);
  EXPECT_NEAR(pm.component[1].m_err, std::sqrt(chi2 / 2 / sxx), 1e-14);
  EXPECT_NEAR(pm.c_plus, pm.component[1].c, 1e-15);  // PSF along e2: c+ is c2
  EXPECT_NEAR(pm.c_cross, -pm.component[0].c, 1e-15);
}

}  // namespace
}  // namespace stampede
