// A set's metacalibrated shear; see metacal_shear.hpp.
#include "engine/analysis/metacal_shear.hpp"

#include <algorithm>
#include <cmath>
#include <map>
#include <stdexcept>
#include <vector>

#include "engine/analysis/bootstrap.hpp"
#include "engine/common/random_stream.hpp"

namespace stampede {
namespace {

// A ring pair (or a lone object): its members' mean e and R, and the selections all its members
// pass.
struct Unit {
  double e1 = 0, e2 = 0;
  std::array<double, 4> r{};
  int members = 0;
  std::uint8_t selected = 0x1f;
};

struct Estimate {
  double g1 = NAN, g2 = NAN, raw1 = NAN, raw2 = NAN;
  std::array<double, 4> r{NAN, NAN, NAN, NAN}, r_sel{NAN, NAN, NAN, NAN};
};

// The estimate from units[i] taken count[i] times.
Estimate estimate_from_units(const std::vector<Unit>& units, std::span<const int> count, double step) {
  // Means over the units passing selection s: e (all s), R (s = 0 only).
  double n[5] = {}, e1[5] = {}, e2[5] = {};
  std::array<double, 4> r{};
  for (std::size_t i = 0; i < units.size(); ++i) {
    if (!count[i]) continue;
    const Unit& u = units[i];
    for (int s = 0; s < 5; ++s) {
      if (!(u.selected >> s & 1)) continue;
      n[s] += count[i];
      e1[s] += count[i] * u.e1;
      e2[s] += count[i] * u.e2;
      if (s == 0)
        for (int k = 0; k < 4; ++k) r[k] += count[i] * u.r[k];
    }
  }
  Estimate out;
  if (n[0] == 0) return out;
  for (int s = 0; s < 5; ++s) {
    if (n[s] == 0) return out;
    e1[s] /= n[s];
    e2[s] /= n[s];
  }
  for (double& v : r) v /= n[0];
  // R_S: rows i = e component, columns j = shear component; s = 1 + 2j (+), 2 + 2j (-).
  out.r_sel = {(e1[1] - e1[2]) / (2 * step), (e1[3] - e1[4]) / (2 * step), (e2[1] - e2[2]) / (2 * step),
               (e2[3] - e2[4]) / (2 * step)};
  out.r = r;
  const double a = r[0] + out.r_sel[0], b = r[1] + out.r_sel[1], c = r[2] + out.r_sel[2], d = r[3] + out.r_sel[3];
  const double det = a * d - b * c;
  out.raw1 = e1[0];
  out.raw2 = e2[0];
  out.g1 = (d * e1[0] - b * e2[0]) / det;
  out.g2 = (-c * e1[0] + a * e2[0]) / det;
  return out;
}

// The rows' units: ring pairs (or lone objects) in order of first appearance.
class MetacalUnits final : public UnitShearEstimator {
 public:
  explicit MetacalUnits(const MetacalRows& rows) : step_(rows.step) {
    const std::size_t n = rows.e1.size();
    bool sizes = rows.e2.size() == n && rows.selected.size() == n && (rows.pair.empty() || rows.pair.size() == n);
    for (const auto& col : rows.r) sizes = sizes && col.size() == n;
    if (!sizes) throw std::invalid_argument("estimate_metacal_set_shear: columns of different lengths");
    for (std::size_t i = 0; i < n; ++i) {
      std::uint8_t sel = rows.selected[i];
      bool finite = std::isfinite(rows.e1[i]) && std::isfinite(rows.e2[i]);
      for (const auto& col : rows.r) finite = finite && std::isfinite(col[i]);
      if (!finite) sel = 0;
      bool added = false;
      const std::size_t u = labels_.unit_of(i, rows.pair, &added);
      if (added) units_.emplace_back();
      Unit& unit = units_[u];
      unit.selected &= sel;
      ++unit.members;
      if (!finite) continue;
      unit.e1 += rows.e1[i];
      unit.e2 += rows.e2[i];
      for (int k = 0; k < 4; ++k) unit.r[k] += rows.r[k][i];
    }
    for (Unit& u : units_) {
      u.e1 /= u.members;
      u.e2 /= u.members;
      for (double& v : u.r) v /= u.members;
      if (u.selected & 1)
        used_ += u.members;
      else
        excluded_ += u.members;
    }
  }

  std::span<const long long> labels() const override { return labels_.labels(); }
  std::array<double, 2> estimate(std::span<const int> count) const override {
    const Estimate e = full_estimate(count);
    return {e.g1, e.g2};
  }
  Estimate full_estimate(std::span<const int> count) const { return estimate_from_units(units_, count, step_); }
  std::array<long long, 5> selected_units() const {
    std::array<long long, 5> n{};
    for (const Unit& u : units_)
      for (int s = 0; s < 5; ++s) n[s] += u.selected >> s & 1;
    return n;
  }
  long long used() const { return used_; }
  long long excluded() const { return excluded_; }

 private:
  std::vector<Unit> units_;
  UnitLabels labels_;
  double step_;
  long long used_ = 0, excluded_ = 0;
};

}  // namespace

std::unique_ptr<UnitShearEstimator> make_metacal_units(const MetacalRows& rows) {
  return std::make_unique<MetacalUnits>(rows);
}

MetacalSetShear estimate_metacal_set_shear(const MetacalRows& rows, double g1_true, double g2_true, int bootstrap,
                                           std::uint64_t seed) {
  const MetacalUnits units(rows);
  MetacalSetShear out;
  out.shear.g1_true = g1_true;
  out.shear.g2_true = g2_true;
  out.shear.used = units.used();
  out.shear.excluded = units.excluded();
  std::vector<int> count(units.labels().size(), 1);
  const Estimate all = units.full_estimate(count);
  out.shear.g1 = all.g1;
  out.shear.g2 = all.g2;
  out.r = all.r;
  out.r_sel = all.r_sel;
  out.g1_raw = all.raw1;
  out.g2_raw = all.raw2;
  out.selected_units = units.selected_units();
  out.shear.units = out.selected_units[0];
  // One selected unit resamples to itself every time: no error (NaN), not a zero one.
  if (bootstrap > 1 && out.shear.units > 1 && std::isfinite(all.g1)) {
    const auto err = bootstrap_errors<2>(&count, bootstrap, seed, [&](const std::vector<int>& c) {
      const Estimate e = units.full_estimate(c);
      return std::array<double, 2>{e.g1, e.g2};
    });
    out.shear.err1 = err[0], out.shear.err2 = err[1];
  }
  return out;
}

}  // namespace stampede
