// Shear metrics; see shear_metrics.hpp.
#include "engine/analysis/shear_metrics.hpp"

#include <cmath>
#include <map>
#include <stdexcept>

#include "engine/common/random_stream.hpp"

namespace stampede {

SetShear estimate_set_shear(std::span<const double> e1, std::span<const double> e2, std::span<const int> usable,
                            std::span<const long long> pair, double g1_true, double g2_true, int bootstrap,
                            std::uint64_t seed) {
  const std::size_t n = e1.size();
  if (e2.size() != n || usable.size() != n || (!pair.empty() && pair.size() != n))
    throw std::invalid_argument("estimate_set_shear: columns of different lengths");
  // Units: a ring pair whose members are all usable, or a lone usable object.
  struct Unit {
    double e1 = 0, e2 = 0;
    int members = 0;
    bool bad = false;
  };
  std::map<long long, Unit> pairs;
  std::vector<Unit> units;
  SetShear s;
  s.g1_true = g1_true;
  s.g2_true = g2_true;
  for (std::size_t i = 0; i < n; ++i) {
    const bool ok = usable[i] && std::isfinite(e1[i]) && std::isfinite(e2[i]);
    if (pair.empty() || pair[i] < 0) {
      if (ok)
        units.push_back({e1[i], e2[i], 1, false});
      else
        ++s.excluded;
      continue;
    }
    Unit& u = pairs[pair[i]];
    ++u.members;
    if (!ok) {
      u.bad = true;
      continue;
    }
    u.e1 += e1[i];
    u.e2 += e2[i];
  }
  for (auto& [label, u] : pairs) {
    if (u.bad) {
      s.excluded += u.members;  // drop the whole pair: its partner alone would not cancel
      continue;
    }
    units.push_back({u.e1 / u.members, u.e2 / u.members, u.members, false});
  }
  if (units.empty()) {
    s.g1 = s.g2 = s.err1 = s.err2 = NAN;
    return s;
  }
  double m1 = 0, m2 = 0;
  long long used = 0;
  for (const Unit& u : units) {
    m1 += u.e1;
    m2 += u.e2;
    used += u.members;
  }
  s.g1 = m1 / units.size();
  s.g2 = m2 / units.size();
  s.used = used;
  // Bootstrap over units.
  if (bootstrap > 1 && units.size() > 1) {
    // splitmix64 is identical on every platform, so bootstrap errors are reproducible.
    std::uint64_t state = seed;
    double a1 = 0, a2 = 0, q1 = 0, q2 = 0;
    for (int b = 0; b < bootstrap; ++b) {
      double b1 = 0, b2 = 0;
      for (std::size_t k = 0; k < units.size(); ++k) {
        const Unit& u = units[splitmix64(state) % units.size()];
        b1 += u.e1;
        b2 += u.e2;
      }
      b1 /= units.size();
      b2 /= units.size();
      a1 += b1;
      a2 += b2;
      q1 += b1 * b1;
      q2 += b2 * b2;
    }
    a1 /= bootstrap;
    a2 /= bootstrap;
    s.err1 = std::sqrt(std::max(0.0, q1 / bootstrap - a1 * a1));
    s.err2 = std::sqrt(std::max(0.0, q2 / bootstrap - a2 * a2));
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
    const double s2 = n > 2 ? chi2 / (n - 2) : 0.0;
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
  if (x1.size() >= 2) {
    m.component[0] = fit_linear_bias(x1, y1, s1);
    m.component[1] = fit_linear_bias(x2, y2, s2);
  } else {
    m.component[0] = m.component[1] = {NAN, NAN, NAN, NAN};
  }
  // c in the PSF frame: rotate by minus twice the PSF position angle.
  const double phi = std::atan2(psf_e2, psf_e1);  // = 2 theta_psf
  const double c1 = m.component[0].c, c2 = m.component[1].c;
  const bool round = psf_e1 == 0 && psf_e2 == 0;
  m.c_plus = round ? c1 : c1 * std::cos(phi) + c2 * std::sin(phi);
  m.c_cross = round ? c2 : -c1 * std::sin(phi) + c2 * std::cos(phi);
  m.q = terms > 0 ? 1e-4 / (sq / terms) : NAN;
  return m;
}

}  // namespace stampede
