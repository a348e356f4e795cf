// The shear of metadetection catalogues (engine/analysis/metadetect_shear): per-type cuts, the
// package's estimator and the composed one. Catalogues are made here from a response whose form is
// known, metacal's step composed with the scene's shear as metacal's images compose them.
#include "engine/analysis/metadetect_shear.hpp"

#include <gtest/gtest.h>

#include <complex>
#include <vector>

namespace stampede {
namespace {

// Rows of `cells` cells whose objects respond to the total shear s (complex reduced shear) as
// e = a s: the noshear image holds the scene's shear g, the 1p, 1m, 2p, 2m images g composed with
// the step, (g + d) / (1 + conj(g) d).
struct Catalogue {
  std::vector<long long> cell, flags;
  std::vector<int> type;
  std::vector<double> e1, e2, snr, t_ratio, mfrac;
  void add(long long c, int t, std::complex<double> e, long long f = 0, double s = 100, double tr = 2, double mf = 0) {
    cell.push_back(c), type.push_back(t), e1.push_back(e.real()), e2.push_back(e.imag());
    flags.push_back(f), snr.push_back(s), t_ratio.push_back(tr), mfrac.push_back(mf);
  }
  MetadetectCellSums sums(const MetadetectCuts& cuts = {}) const {
    return sum_metadetect_cells(cell, type, e1, e2, flags, snr, t_ratio, mfrac, cuts);
  }
};

Catalogue linear_response(std::complex<double> g, double a, double step, int cells) {
  const std::complex<double> d[5] = {0.0, step, -step, {0, step}, {0, -step}};
  Catalogue c;
  for (int k = 0; k < cells; ++k)
    for (int t = 0; t < 5; ++t) {
      const std::complex<double> s = (g + d[t]) / (1.0 + std::conj(g) * d[t]);
      c.add(k, t, a * s);
    }
  return c;
}

TEST(MetadetectShear, TheComposedEstimatorReadsTheShearThePackagesReadsHighByGSquared) {
  const double step = 0.01, a = 0.4;
  for (const std::complex<double> g : {std::complex<double>(0.02, 0.0), std::complex<double>(0.03, -0.02)}) {
    const Catalogue plus = linear_response(g, a, step, 4), minus = linear_response(-g, a, step, 4);
    const MetadetectBias composed =
        metadetect_pair_bias(plus.sums(), minus.sums(), g.real(), g.imag(), step, 20, 1, MetadetectEstimator::kComposed);
    const MetadetectBias package =
        metadetect_pair_bias(plus.sums(), minus.sums(), g.real(), g.imag(), step, 20, 1, MetadetectEstimator::kPackage);
    const double g2 = std::norm(g);
    // R = a (1 - |g|^2) to O(step^2 |g|^2): the package reads g / (1 - |g|^2), m = |g|^2 / (1 - |g|^2).
    EXPECT_NEAR(package.m1, g2 / (1 - g2), 1e-3 * g2) << g;
    EXPECT_NEAR(composed.m1, 0.0, 1e-7) << g;
    if (g.imag() != 0) {
      EXPECT_NEAR(package.m2, g2 / (1 - g2), 1e-3 * g2) << g;
      EXPECT_NEAR(composed.m2, 0.0, 1e-7) << g;
    }
    // c from the pair's sum: zero for either.
    EXPECT_NEAR(composed.c2, 0.0, 1e-12);
    EXPECT_NEAR(package.c2, 0.0, 1e-12);
    // One catalogue: g itself, and R as measured.
    const MetadetectShear s = metadetect_shear(plus.sums(), step, 20, 1, MetadetectEstimator::kComposed);
    EXPECT_NEAR(s.g1, g.real(), 1e-7 * std::abs(g));
    EXPECT_NEAR(s.g2, g.imag(), 1e-7 * std::abs(g));
    EXPECT_NEAR(s.r11, a * (1 - g2), 1e-6);
    const MetadetectShear p = metadetect_shear(plus.sums(), step, 20, 1, MetadetectEstimator::kPackage);
    EXPECT_EQ(p.r11, s.r11);
    EXPECT_NEAR(p.g1, g.real() / (1 - g2), 1e-7 * std::abs(g));
  }
}

TEST(MetadetectShear, EachTypesRowsAreCutOnTheirOwnQuantities) {
  Catalogue c = linear_response({0.02, 0.0}, 0.4, 0.01, 1);
  // Rows that every cut removes: a flag, S/N 10 (the cut is strict), T_ratio 1.2, a NaN e.
  c.add(0, 0, {0.9, 0.9}, 1);
  c.add(0, 0, {0.9, 0.9}, 0, 10.0);
  c.add(0, 1, {0.9, 0.9}, 0, 100, 1.2);
  c.add(0, 2, {NAN, 0.0});
  const MetadetectCellSums s = c.sums();
  ASSERT_EQ(s.cells.size(), 1u);
  for (int t = 0; t < 5; ++t) EXPECT_EQ(s.sums[0][t].n, 1) << t;
  MetadetectCuts loose;
  loose.min_snr = 5, loose.min_t_ratio = 1.0, loose.excluded_flags = 0;
  const MetadetectCellSums l = c.sums(loose);
  EXPECT_EQ(l.sums[0][0].n, 3);
  EXPECT_EQ(l.sums[0][1].n, 2);
  EXPECT_EQ(l.sums[0][2].n, 1);  // a NaN e is never kept
}

TEST(MetadetectEstimator, NamesParseBack) {
  for (MetadetectEstimator e : {MetadetectEstimator::kComposed, MetadetectEstimator::kPackage}) {
    MetadetectEstimator parsed;
    ASSERT_TRUE(parse_metadetect_estimator(metadetect_estimator_name(e), &parsed));
    EXPECT_EQ(parsed, e);
  }
  MetadetectEstimator e;
  EXPECT_TRUE(parse_metadetect_estimator("Package", &e));
  EXPECT_FALSE(parse_metadetect_estimator("second-order", &e));
}

}  // namespace
}  // namespace stampede
