// Shear metrics on synthetic catalogues with a known multiplicative and additive bias.
#include "engine/analysis/shear_metrics.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <random>

namespace stampede {
namespace {

// Sets of ring pairs with shear g: e_est = (1 + m) g + c + e_int + noise, partners with -e_int.
SetShear synthetic_set(double g1, double g2, double m1, double m2, double c1, double c2, int pairs, double noise,
                       std::mt19937_64& rng) {
  std::normal_distribution<double> shape(0.0, 0.25), err(0.0, noise);
  std::vector<double> e1, e2;
  std::vector<int> usable;
  std::vector<long long> pair;
  for (int p = 0; p < pairs; ++p) {
    const double i1 = shape(rng), i2 = shape(rng);
    for (double sign : {1.0, -1.0}) {
      e1.push_back((1 + m1) * g1 + c1 + sign * i1 + err(rng));
      e2.push_back((1 + m2) * g2 + c2 + sign * i2 + err(rng));
      usable.push_back(1);
      pair.push_back(p);
    }
  }
  return estimate_set_shear(e1, e2, usable, pair, g1, g2, 200, 42);
}

TEST(ShearMetrics, RecoversInjectedMultiplicativeAndAdditiveBias) {
  std::mt19937_64 rng(7);
  const double m1 = 0.02, m2 = -0.01, c1 = 3e-4, c2 = -2e-4;
  std::vector<SetShear> sets;
  for (int k = 0; k < 8; ++k) {
    const double g1 = -0.05 + 0.1 * k / 7.0, g2 = 0.04 - 0.08 * ((k * 3) % 8) / 7.0;
    sets.push_back(synthetic_set(g1, g2, m1, m2, c1, c2, 2000, 0.02, rng));
  }
  const ShearMetrics r = combine_sets(sets, 0.0, 0.0);
  std::printf("m1 = %.4f +- %.4f, m2 = %.4f +- %.4f, c1 = %.2e +- %.1e, c2 = %.2e +- %.1e, Q = %.0f\n", r.component[0].m,
              r.component[0].m_err, r.component[1].m, r.component[1].m_err, r.component[0].c, r.component[0].c_err,
              r.component[1].c, r.component[1].c_err, r.q);
  // Within 3 sigma of the truth, and the quoted errors are the right size (noise 0.02 / sqrt(2000 pairs)
  // per set -> ~3e-4 per set estimate; m errors ~ that / spread of g ~ 1e-2).
  EXPECT_NEAR(r.component[0].m, m1, 3 * r.component[0].m_err);
  EXPECT_NEAR(r.component[1].m, m2, 3 * r.component[1].m_err);
  EXPECT_NEAR(r.component[0].c, c1, 3 * r.component[0].c_err);
  EXPECT_NEAR(r.component[1].c, c2, 3 * r.component[1].c_err);
  EXPECT_LT(r.component[0].m_err, 0.02);
  EXPECT_GT(r.component[0].m_err, 1e-4);
  // Pair averaging removed the shape noise entirely: each set's error is the measurement noise only.
  EXPECT_NEAR(sets[0].err1, 0.02 / std::sqrt(2.0) / std::sqrt(2000.0), 0.3 * 0.02 / std::sqrt(4000.0));
}

TEST(ShearMetrics, QualityFactorMatchesHandComputation) {
  std::vector<SetShear> sets(2);
  sets[0].g1_true = 0.01, sets[0].g2_true = -0.02, sets[0].g1 = 0.0101, sets[0].g2 = -0.0203;
  sets[1].g1_true = -0.03, sets[1].g2_true = 0.04, sets[1].g1 = -0.0298, sets[1].g2 = 0.0400;
  const ShearMetrics r = combine_sets(sets, 0.0, 0.0);
  const double mean_sq = (1e-8 + 9e-8 + 4e-8 + 0.0) / 4.0;
  EXPECT_NEAR(r.q, 1e-4 / mean_sq, 1e-9 * r.q);
}

TEST(ShearMetrics, FlaggedRingMembersDropTheirPair) {
  const std::vector<double> e1 = {0.3, -0.3, 0.1, -0.1, 0.5}, e2 = {0.0, 0.0, 0.2, -0.2, 0.0};
  const std::vector<int> usable = {1, 1, 1, 0, 1};
  const std::vector<long long> pair = {0, 0, 1, 1, -1};
  const SetShear s = estimate_set_shear(e1, e2, usable, pair, 0, 0, 0, 1);
  EXPECT_EQ(s.used, 3);      // pair 0 and the lone object 4
  EXPECT_EQ(s.excluded, 2);  // the flagged object and its partner
  EXPECT_DOUBLE_EQ(s.g1, (0.0 + 0.5) / 2.0);
}

TEST(ShearMetrics, AdditiveBiasInThePsfFrame) {
  // PSF along y = x (e2 > 0): c_plus is the component along e2, c_cross = -c1.
  std::vector<SetShear> sets(3);
  for (int k = 0; k < 3; ++k) {
    sets[k].g1_true = sets[k].g2_true = 0.01 * k;
    sets[k].g1 = sets[k].g1_true + 1e-3;
    sets[k].g2 = sets[k].g2_true + 2e-3;
  }
  const ShearMetrics r = combine_sets(sets, 0.0, 0.05);
  EXPECT_NEAR(r.c_plus, 2e-3, 1e-12);
  EXPECT_NEAR(r.c_cross, -1e-3, 1e-12);
  EXPECT_NEAR(r.component[0].m, 0.0, 1e-9);
}

TEST(ShearMetrics, BootstrapIsDeterministicPerSeed) {
  std::mt19937_64 a(1), b(1);
  const SetShear x = synthetic_set(0.01, 0.02, 0, 0, 0, 0, 100, 0.05, a);
  const SetShear y = synthetic_set(0.01, 0.02, 0, 0, 0, 0, 100, 0.05, b);
  EXPECT_EQ(x.err1, y.err1);
  EXPECT_EQ(x.err2, y.err2);
}

// One usable ring pair: every bootstrap resample is that pair, so its spread (0) is no error: the
// errors are NaN, and a line through two such sets has NaN m and c errors too (two points leave no
// scatter); three sets give errors from the scatter.
TEST(ShearMetrics, AnErrorFromFewerThanTwoRingPairsIsNotComputed) {
  auto one_pair_set = [](double g1, double offset) {
    const std::vector<double> e1 = {g1 + 0.2 + offset, g1 - 0.2 + offset, 0.5, -0.1}, e2 = {0.1, -0.1, 0.3, 0.2};
    const std::vector<int> usable = {1, 1, 0, 1};  // pair 1 has an unusable member
    const std::vector<long long> pair = {0, 0, 1, 1};
    return estimate_set_shear(e1, e2, usable, pair, g1, -g1, 200, 3);
  };
  const SetShear a = one_pair_set(0.01, 0.0), b = one_pair_set(0.03, 1e-3), c = one_pair_set(-0.02, -1e-3);
  EXPECT_EQ(a.units, 1);
  EXPECT_EQ(a.used, 2);
  EXPECT_NEAR(a.g1, 0.01, 1e-15);
  EXPECT_TRUE(std::isnan(a.err1)) << a.err1;
  EXPECT_TRUE(std::isnan(a.err2)) << a.err2;
  const ShearMetrics two = combine_sets({a, b}, 0.0, 0.0);
  EXPECT_NEAR(two.component[0].m, 0.05, 1e-12);  // through both points exactly
  EXPECT_TRUE(std::isnan(two.component[0].m_err)) << two.component[0].m_err;
  EXPECT_TRUE(std::isnan(two.component[0].c_err)) << two.component[0].c_err;
  const ShearMetrics three = combine_sets({a, b, c}, 0.0, 0.0);
  EXPECT_GT(three.component[0].m_err, 0.0);
  EXPECT_TRUE(std::isfinite(three.component[0].m_err));
  // Two usable pairs have a bootstrap error; --bootstrap 1 (or 0) computes none.
  const std::vector<double> e = {0.2, -0.2, 0.3, -0.25};
  const std::vector<int> all(4, 1);
  const std::vector<long long> pair = {0, 0, 1, 1};
  EXPECT_GT(estimate_set_shear(e, e, all, pair, 0, 0, 200, 3).err1, 0.0);
  EXPECT_TRUE(std::isnan(estimate_set_shear(e, e, all, pair, 0, 0, 1, 3).err1));
}

// Two fits of one set (a plain and a metacal table, pooled by the report) have one true shear: no
// line through them. m and c are NaN, not an exception that ended the report in a traceback.
TEST(ShearMetrics, SetsOfOneTrueShearHaveNoLine) {
  SetShear a, b;
  a.g1_true = b.g1_true = 0.02, a.g2_true = b.g2_true = -0.01;
  a.g1 = 0.021, b.g1 = 0.019, a.g2 = -0.011, b.g2 = -0.009;
  a.err1 = a.err2 = b.err1 = b.err2 = 1e-3;
  a.used = b.used = 10;
  const ShearMetrics m = combine_sets({a, b}, 0.0, 0.0);
  for (const BiasFit& f : m.component) EXPECT_TRUE(std::isnan(f.m) && std::isnan(f.c)) << f.m << " " << f.c;
  EXPECT_GT(m.q, 0.0);  // Q needs no line
  b.g2_true = 0.03;     // one component's true shears still equal: still no line
  EXPECT_TRUE(std::isnan(combine_sets({a, b}, 0.0, 0.0).component[1].m));
}

}  // namespace
}  // namespace stampede
