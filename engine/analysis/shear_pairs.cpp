// Shear-pair estimates; see shear_pairs.hpp.
#include "engine/analysis/shear_pairs.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>

#include "engine/analysis/bootstrap.hpp"
#include "engine/common/random_stream.hpp"

namespace stampede {
namespace {

struct PairValues {
  std::array<double, 2> difference, sum;
};

PairValues combine(std::array<double, 2> plus, std::array<double, 2> minus) {
  return {{0.5 * (plus[0] - minus[0]), 0.5 * (plus[1] - minus[1])},
          {0.5 * (plus[0] + minus[0]), 0.5 * (plus[1] + minus[1])}};
}

// y = slope x through the origin (m) and y = c (a mean), weighted by 1/err^2, or by 1 with errors
// from the scatter when any error is missing.
struct Line {
  double value = NAN, err = NAN;
};

Line fit_through_origin(const std::vector<double>& x, const std::vector<double>& y, const std::vector<double>& err) {
  const std::size_t n = x.size();
  bool weighted = true;
  for (double e : err) weighted &= e > 0 && std::isfinite(e);
  double sxx = 0, sxy = 0;
  for (std::size_t i = 0; i < n; ++i) {
    const double w = weighted ? 1 / (err[i] * err[i]) : 1.0;
    sxx += w * x[i] * x[i];
    sxy += w * x[i] * y[i];
  }
  if (!(sxx > 0)) return {};
  Line l{sxy / sxx, std::sqrt(1 / sxx)};
  if (!weighted) {
    double chi2 = 0;
    for (std::size_t i = 0; i < n; ++i) chi2 += std::pow(y[i] - l.value * x[i], 2);
    l.err = n > 1 ? std::sqrt(chi2 / (n - 1) / sxx) : NAN;
  }
  return l;
}

Line weighted_mean(const std::vector<double>& y, const std::vector<double>& err) {
  const std::size_t n = y.size();
  if (n == 0) return {};
  bool weighted = true;
  for (double e : err) weighted &= e > 0 && std::isfinite(e);
  double sw = 0, sy = 0;
  for (std::size_t i = 0; i < n; ++i) {
    const double w = weighted ? 1 / (err[i] * err[i]) : 1.0;
    sw += w;
    sy += w * y[i];
  }
  Line l{sy / sw, std::sqrt(1 / sw)};
  if (!weighted) {
    double ss = 0;
    for (double v : y) ss += (v - l.value) * (v - l.value);
    l.err = n > 1 ? std::sqrt(ss / (n - 1) / n) : NAN;
  }
  return l;
}

}  // namespace

ShearPairEstimate estimate_shear_pair(const UnitShearEstimator& plus, const UnitShearEstimator& minus,
                                      double g1_true, double g2_true, int bootstrap, std::uint64_t seed) {
  const auto labels = plus.labels();
  if (!std::ranges::equal(labels, minus.labels()))
    throw std::invalid_argument("estimate_shear_pair: the two sets do not list the same objects and ring pairs");
  ShearPairEstimate out;
  out.g1_true = g1_true;
  out.g2_true = g2_true;
  std::vector<int> count(labels.size(), 1);
  const PairValues all = combine(plus.estimate(count), minus.estimate(count));
  out.half_difference = all.difference;
  out.half_sum = all.sum;
  out.half_difference_err = out.half_sum_err = {NAN, NAN};
  if (bootstrap > 1 && labels.size() > 1) {
    const auto err = bootstrap_errors<4>(&count, bootstrap, seed, [&](const std::vector<int>& c) {
      const PairValues v = combine(plus.estimate(c), minus.estimate(c));
      return std::array<double, 4>{v.difference[0], v.difference[1], v.sum[0], v.sum[1]};
    });
    out.half_difference_err = {err[0], err[1]};
    out.half_sum_err = {err[2], err[3]};
  }
  return out;
}

ShearPairMetrics combine_shear_pairs(const std::vector<ShearPairEstimate>& pairs, double psf_e1, double psf_e2) {
  ShearPairMetrics out;
  for (int c = 0; c < 2; ++c) {
    std::vector<double> g, d, d_err, s, s_err;
    for (const ShearPairEstimate& p : pairs) {
      if (!std::isfinite(p.half_difference[c]) || !std::isfinite(p.half_sum[c])) continue;
      g.push_back(c == 0 ? p.g1_true : p.g2_true);
      d.push_back(p.half_difference[c]);
      d_err.push_back(p.half_difference_err[c]);
      s.push_back(p.half_sum[c]);
      s_err.push_back(p.half_sum_err[c]);
    }
    const Line slope = fit_through_origin(g, d, d_err), offset = weighted_mean(s, s_err);
    out.component[c] = {slope.value - 1, slope.err, offset.value, offset.err};
  }
  rotate_into_psf_frame(out.component[0].c, out.component[1].c, psf_e1, psf_e2, &out.c_plus, &out.c_cross);
  return out;
}

}  // namespace stampede
