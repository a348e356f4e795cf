// The calibration simulations: grid order, stamps at the reference S/N with the requested shape,
// noise pairs that cancel exactly, resumable sources, and the per-point bias reduction.
#include "engine/calibration/calibration_grid.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <vector>

#include "engine/model/parameters.hpp"

namespace stampede {
namespace {

CalibrationGridOptions small_grid() {
  CalibrationGridOptions o;
  o.radii = {1.5, 3.0};
  o.bulge_fractions = {0.0, 1.0};
  o.e_steps = 5;
  o.e_max = 0.6;
  o.realisations = 3;
  o.stamp_size = 31;
  o.psf.kind = PsfKind::kMoffat;
  o.psf.moffat = {3.0, 2.85, 0.0, 0.05, 0.0};
  return o;
}

TEST(CalibrationGrid, PointsRunOverRadiusFractionAxisAndE) {
  const CalibrationGrid grid(small_grid());
  const auto& p = grid.points();
  ASSERT_EQ(p.size(), 2u * 2 * 2 * 5);
  EXPECT_EQ(grid.objects(), static_cast<long long>(p.size()) * 6);
  for (std::size_t i = 0; i < p.size(); ++i) {
    EXPECT_EQ(p[i].index, static_cast<int>(i));
    EXPECT_EQ(p[i].radius, i < 20 ? 1.5 : 3.0);
    EXPECT_EQ(p[i].bulge_fraction, (i / 10) % 2 ? 1.0 : 0.0);
    EXPECT_EQ(p[i].axis, (i / 5) % 2 ? BiasAxis::kE2 : BiasAxis::kE1);
    EXPECT_NEAR(p[i].e_true, -0.6 + 0.3 * static_cast<double>(i % 5), 1e-15);
    EXPECT_EQ(p[i].e1() + p[i].e2(), p[i].e_true);
    EXPECT_EQ(p[i].e1() * p[i].e2(), 0.0);
  }
}

// Second moments of a stamp about its centroid: e = (Qxx - Qyy, 2 Qxy) / (Qxx + Qyy) (+ 2 sqrt det).
void stamp_shape(const std::vector<double>& s, int n, double* cx, double* cy, double* e1, double* e2) {
  double f = 0, x1 = 0, y1 = 0;
  for (int y = 0; y < n; ++y)
    for (int x = 0; x < n; ++x) {
      f += s[y * n + x];
      x1 += x * s[y * n + x];
      y1 += y * s[y * n + x];
    }
  *cx = x1 / f, *cy = y1 / f;
  double qxx = 0, qyy = 0, qxy = 0;
  for (int y = 0; y < n; ++y)
    for (int x = 0; x < n; ++x) {
      const double dx = x - *cx, dy = y - *cy, v = s[y * n + x];
      qxx += v * dx * dx;
      qyy += v * dy * dy;
      qxy += v * dx * dy;
    }
  const double d = qxx + qyy + 2 * std::sqrt(qxx * qyy - qxy * qxy);
  *e1 = (qxx - qyy) / d;
  *e2 = 2 * qxy / d;
}

TEST(CalibrationGrid, StampsHaveTheReferenceSnrAndTheirPointsShape) {
  const CalibrationGridOptions o = small_grid();
  const CalibrationGrid grid(o);
  SimWorkspace ws;
  const int n = o.stamp_size;
  std::vector<double> stamp(n * n);
  for (int k : {0, 2, 4, 5, 9, 24, 39}) {
    const CalibrationPoint& p = grid.points()[k];
    grid.render(p, stamp, ws);
    double sum2 = 0;
    for (double v : stamp) sum2 += v * v;
    EXPECT_NEAR(std::sqrt(sum2) / o.noise_sigma, o.snr, 1e-9 * o.snr);
    double cx, cy, e1, e2;
    stamp_shape(stamp, n, &cx, &cy, &e1, &e2);
    EXPECT_NEAR(cx, 0.5 * (n - 1), 1e-6);
    EXPECT_NEAR(cy, 0.5 * (n - 1), 1e-6);
    // The PSF (e2 = 0.05) rounds and skews the observed shape; the sign and the axis are the point's.
    if (p.e_true == 0) continue;
    const double along = p.axis == BiasAxis::kE1 ? e1 : e2;
    EXPECT_GT(along * p.e_true, 0.0) << k;
    EXPECT_LT(std::abs(along), std::abs(p.e_true)) << k;
    if (p.axis == BiasAxis::kE2) {
      EXPECT_LT(std::abs(e1), 1e-6) << k;  // symmetric about the e2 axis
    }
  }
}

TEST(CalibrationGrid, SourceDrawsNoisePairsAndResumesIdentically) {
  const CalibrationGridOptions o = small_grid();
  const CalibrationGrid grid(o);
  const int n = o.stamp_size;
  CalibrationSource source(grid);
  StampBatch batch(16);
  ASSERT_TRUE(source.fill(batch));
  ASSERT_EQ(batch.count, 16);
  const auto stamp = [](const StampBatch& b, int k) { return b.observations.pixels(b.observations.first_of(k)); };
  SimWorkspace ws;
  std::vector<double> clean(n * n);
  grid.render(grid.points()[0], clean, ws);
  for (int k = 0; k < 6; k += 2) {  // point 0: three pairs
    EXPECT_EQ(batch.records[k].id, k);
    double max_error = 0, noise2 = 0;
    for (int i = 0; i < n * n; ++i) {
      max_error = std::max(max_error, std::abs(0.5 * (stamp(batch, k)[i] + stamp(batch, k + 1)[i]) - clean[i]));
      noise2 += (stamp(batch, k)[i] - clean[i]) * (stamp(batch, k)[i] - clean[i]);
    }
    EXPECT_LT(max_error, 1e-12);
    EXPECT_NEAR(std::sqrt(noise2 / (n * n)), o.noise_sigma, 0.1);
  }
  // Realisations differ from each other.
  EXPECT_NE(stamp(batch, 0)[100], stamp(batch, 2)[100]);
  // A source positioned at object 10 gives what the first one gives there.
  CalibrationSource resumed(grid);
  resumed.skip_to(10);
  StampBatch other(6);
  ASSERT_TRUE(resumed.fill(other));
  for (int k = 0; k < 6; ++k) {
    EXPECT_EQ(other.records[k].id, 10 + k);
    for (int i = 0; i < n * n; ++i) ASSERT_EQ(stamp(other, k)[i], stamp(batch, 10 + k)[i]);
  }
  // The end: every object once.
  long long seen = 16;
  while (source.fill(batch)) seen += batch.count;
  EXPECT_EQ(seen, grid.objects());
}

ObjectRecord fitted(long long id, double e1, double e2, bool usable = true) {
  ObjectRecord r;
  r.id = id;
  r.fit.status = usable ? FitStatus::kOk : FitStatus::kMaxIterations;
  r.fit.params[index(Param::kE1)] = e1;
  r.fit.params[index(Param::kE2)] = e2;
  return r;
}

TEST(CalibrationGrid, AccumulatorAveragesNoisePairsPerPoint) {
  const CalibrationGrid grid(small_grid());  // 3 pairs per point
  std::vector<std::pair<int, PointBias>> out;
  PointBiasAccumulator acc(grid, [&](int p, const PointBias& b) { out.emplace_back(p, b); });
  const CalibrationPoint& p0 = grid.points()[0];  // e1 = -0.6
  const CalibrationPoint& p1 = grid.points()[1];  // e1 = -0.3
  // Point 0: pair means of e1 - e_true: +0.01, +0.03, +0.02; e2: 0.001 each.
  std::vector<ObjectRecord> rows = {fitted(0, p0.e_true + 0.05, 0.0), fitted(1, p0.e_true - 0.03, 0.002),
                                    fitted(2, p0.e_true + 0.06, 0.001), fitted(3, p0.e_true + 0.00, 0.001),
                                    fitted(4, p0.e_true + 0.02, 0.003), fitted(5, p0.e_true + 0.02, -0.001)};
  acc.add(rows);
  ASSERT_EQ(out.size(), 1u);
  EXPECT_EQ(out[0].first, 0);
  EXPECT_EQ(out[0].second.pairs_used, 3);
  EXPECT_NEAR(out[0].second.bias[0], 0.02, 1e-15);
  EXPECT_NEAR(out[0].second.error[0], 0.01 / std::sqrt(3.0), 1e-15);  // sample sd 0.01
  EXPECT_NEAR(out[0].second.bias[1], 0.001, 1e-15);
  // Point 1, in two calls: one pair lost to a flagged member.
  std::vector<ObjectRecord> a = {fitted(6, p1.e_true + 0.1, 0), fitted(7, p1.e_true, 0, false)};
  std::vector<ObjectRecord> b = {fitted(8, p1.e_true + 0.01, 0), fitted(9, p1.e_true + 0.01, 0),
                                 fitted(10, p1.e_true + 0.03, 0), fitted(11, p1.e_true + 0.01, 0)};
  acc.add(a);
  EXPECT_EQ(out.size(), 1u);
  acc.add(b);
  ASSERT_EQ(out.size(), 2u);
  EXPECT_EQ(out[1].second.pairs_used, 2);
  EXPECT_EQ(out[1].second.pairs_failed, 1);
  EXPECT_NEAR(out[1].second.bias[0], 0.015, 1e-15);
  // Out of order is a programming error.
  std::vector<ObjectRecord> skip = {fitted(13, 0, 0)};
  EXPECT_THROW(acc.add(skip), std::logic_error);
}

TEST(CalibrationGrid, InvalidOptionsNameTheOption) {
  auto message = [](CalibrationGridOptions o) {
    std::string why;
    EXPECT_FALSE(o.IsValid(&why));
    return why;
  };
  CalibrationGridOptions o = small_grid();
  o.radii = {2.0, 1.0};
  EXPECT_NE(message(o).find("radii 2,1"), std::string::npos);
  o = small_grid();
  o.bulge_fractions = {0.0, 1.5};
  EXPECT_NE(message(o).find("bulge_fractions"), std::string::npos);
  o = small_grid();
  o.e_steps = 3;
  EXPECT_NE(message(o).find("e_steps 3"), std::string::npos);
  o = small_grid();
  o.noise_sigma = 0;
  EXPECT_NE(message(o).find("noise_sigma"), std::string::npos);
  o = small_grid();
  o.realisations = 1;
  EXPECT_NE(message(o).find("realisations 1"), std::string::npos);
  o = small_grid();
  o.psf.kind = PsfKind::kImage;
  EXPECT_NE(message(o).find("psf_input"), std::string::npos);
  EXPECT_THROW(CalibrationGrid{o}, std::invalid_argument);
}

}  // namespace
}  // namespace stampede
