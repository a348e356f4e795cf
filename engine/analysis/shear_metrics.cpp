// Shear metrics; see shear_metrics.hpp.
#include "engine/analysis/shear_metrics.hpp"

#include <algorithm>
#include <cmath>
#include <map>
#include <stdexcept>

#include "engine/analysis/bootstrap.hpp"
#include "engine/common/random_stream.hpp"

namespace stampede {

namespace {

// Ring pairs (all members usable) and lone usable objects, in order of first appearance.
class ShearUnits final : public UnitShearEstimator {
 public:
  ShearUnits(std::span<const double> e1, std::span<const double> e2, std::span<const int> usable,
             std::span<const long long> pair) {
    const std::size_t n = e1.size();
    if (e2.size() != n || usable.size() != n || (!pair.empty() && pair.size() != n))
      throw std::invalid_argument("estimate_set_shear: columns of different lengths");
    for (std::size_t i = 0; i < n; ++i) {
      const bool ok = usable[i] && std::isfinite(e1[i]) && std::isfinite(e2[i]);
      bool added = false;
      const std::size_t u = labels_.unit_of(i, pair, &added);
      if (added) units_.emplace_back();
      Unit& unit = units_[u];
      ++unit.members;
      unit.bad |= !ok;
      if (ok) unit.e1 += e1[i], unit.e2 += e2[i];
    }
    for (Unit& u : units_) {
      if (u.bad) {
        excluded_ += u.members;  // the whole pair: its partner alone would not cancel
        continue;
      }
      u.e1 /= u.members;
      u.e2 /= u.members;
      used_ += u.members;
    }
  }

  std::span<const long long> labels() const override { return labels_.labels(); }
  long long usable_units() const {
    return std::count_if(units_.begin(), units_.end(), [](const Unit& u) { return !u.bad; });
  }

  std::array<double, 2> estimate(std::span<const int> count) const override {
    double n = 0, m1 = 0, m2 = 0;
    for (std::size_t i = 0; i < units_.size(); ++i) {
      if (units_[i].bad || !count[i]) continue;
      n += count[i];
      m1 += count[i] * units_[i].e1;
      m2 += count[i] * units_[i].e2;
    }
    if (n == 0) return {NAN, NAN};
    return {m1 / n, m2 / n};
  }

  long long used() const { return used_; }
  long long excluded() const { return excluded_; }

 private:
  struct Unit {
    double e1 = 0, e2 = 0;
    int members = 0;
    bool bad = false;
  };
  std::vector<Unit> units_;
  UnitLabels labels_;
  long long used_ = 0, excluded_ = 0;
};

}  // namespace

std::unique_ptr<UnitShearEstimator> make_shear_units(std::span<const double> e1, std::span<const double> e2,
                                                     std::span<const int> usable, std::span<const long long> pair) {
  return std::make_unique<ShearUnits>(e1, e2, usable, pair);
}

SetShear estimate_set_shear(std::span<const double> e1, std::span<const double> e2, std::span<const int> usable,
                            std::span<const long long> pair, double g1_true, double g2_true, int bootstrap,
                            std::uint64_t seed) {
  const ShearUnits units(e1, e2, usable, pair);
  SetShear s;
  s.g1_true = g1_true;
  s.g2_true = g2_true;
  s.used = units.used();
  s.excluded = units.excluded();
  s.units = units.usable_units();
  const std::size_t n = units.labels().size();
  std::vector<int> count(n, 1);
  const auto g = units.estimate(count);
  s.g1 = g[0];
  s.g2 = g[1];
  if (!std::isfinite(s.g1)) return s;
  // One usable unit resamples to itself every time: no error (NaN), not a zero one.
  if (bootstrap > 1 && s.units > 1) {
    const auto err = bootstrap_errors<2>(&count, bootstrap, seed, [&](const std::vector<int>& c) {
      const auto e = units.estimate(c);
      return std::array<double, 2>{e[0], e[1]};
    });
    s.err1 = err[0], s.err2 = err[1];
  }
  return s;
}

BiasFit fit_linear_bias(std::span<const double> x, std::span<const double> y, std::span<const double> err) {
  const std::size_t n = x.size();
  if (y.size() != n || err.size() != n || n < 2) throw std::invalid_argument("fit_linear_bias: need >= 2 sets");
  bool weighted = true;
  for (double e : err) weighted &= e > 0 && std::isfinite(e);
  double sw = 0, sx = 0, sy = 0, sxx = 0, sxy = 0;
  for (std::size_t i = 0; i < n; ++i) {
    const double w = weighted ? 1.0 / (err[i] * err[i]) : 1.0;
    sw += w;
    sx += w * x[i];
    sy += w * y[i];
    sxx += w * x[i] * x[i];
    sxy += w * x[i] * y[i];
  }
  const double det = sw * sxx - sx * sx;
  if (!(det > 0)) throw std::invalid_argument("fit_linear_bias: the true shears do not vary between sets");
  const double slope = (sw * sxy - sx * sy) / det, intercept = (sxx * sy - sx * sxy) / det;
  BiasFit f;
  f.m = slope - 1.0;
  f.c = intercept;
  double var_slope = sw / det, var_intercept = sxx / det;
  if (!weighted) {
    // Errors from the scatter about the line (unit weights).
    double chi2 = 0;
    for (std::size_t i = 0; i < n; ++i) chi2 += std::pow(y[i] - slope * x[i] - intercept, 2);
    const double s2 = n > 2 ? chi2 / static_cast<double>(n - 2) : NAN;
    var_slope *= s2;
    var_intercept *= s2;
  }
  f.m_err = std::sqrt(var_slope);
  f.c_err = std::sqrt(var_intercept);
  return f;
}

ShearMetrics combine_sets(std::vector<SetShear> sets, double psf_e1, double psf_e2) {
  ShearMetrics m;
  std::vector<double> x1, y1, s1, x2, y2, s2;
  double sq = 0;
  int terms = 0;
  for (const SetShear& s : sets) {
    if (!std::isfinite(s.g1) || !std::isfinite(s.g2)) continue;
    x1.push_back(s.g1_true), y1.push_back(s.g1), s1.push_back(s.err1);
    x2.push_back(s.g2_true), y2.push_back(s.g2), s2.push_back(s.err2);
    sq += std::pow(s.g1 - s.g1_true, 2) + std::pow(s.g2 - s.g2_true, 2);
    terms += 2;
  }
  m.sets = std::move(sets);
  // A line needs two distinct true shears per component (two fits of one set have one): else m and
  // c are not defined, and NaN says so.
  auto varies = [](const std::vector<double>& x) {
    return std::any_of(x.begin(), x.end(), [&](double v) { return v != x[0]; });
  };
  if (x1.size() >= 2 && varies(x1) && varies(x2)) {
    m.component[0] = fit_linear_bias(x1, y1, s1);
    m.component[1] = fit_linear_bias(x2, y2, s2);
  } else {
    m.component[0] = m.component[1] = {NAN, NAN, NAN, NAN};
  }
  rotate_into_psf_frame(m.component[0].c, m.component[1].c, psf_e1, psf_e2, &m.c_plus, &m.c_cross);
  m.q = terms > 0 ? 1e-4 / (sq / terms) : NAN;
  return m;
}

void rotate_into_psf_frame(double c1, double c2, double psf_e1, double psf_e2, double* c_plus, double* c_cross) {
  // Rotate by minus twice the PSF position angle.
  const double phi = std::atan2(psf_e2, psf_e1);  // = 2 theta_psf
  const bool round = psf_e1 == 0 && psf_e2 == 0;
  *c_plus = round ? c1 : c1 * std::cos(phi) + c2 * std::sin(phi);
  *c_cross = round ? c2 : -c1 * std::sin(phi) + c2 * std::cos(phi);
}

}  // namespace stampede
