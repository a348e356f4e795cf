// Shear from metadetection catalogues; see metadetect_shear.hpp.
#include "engine/analysis/metadetect_shear.hpp"

#include <cctype>
#include <cmath>
#include <map>
#include <stdexcept>

#include "engine/analysis/bootstrap.hpp"

namespace stampede {
namespace {

using Sums = MetadetectCellSums::Sums;

// Pooled sums of each type over cells, cell k counted count[k] times (all once when empty).
std::array<Sums, 5> pooled(const MetadetectCellSums& s, const std::vector<int>& count) {
  std::array<Sums, 5> out{};
  for (std::size_t k = 0; k < s.sums.size(); ++k) {
    const double w = count.empty() ? 1.0 : count[k];
    if (w == 0) continue;
    for (int t = 0; t < 5; ++t)
      out[t].n += w * s.sums[k][t].n, out[t].e1 += w * s.sums[k][t].e1, out[t].e2 += w * s.sums[k][t].e2;
  }
  return out;
}

double mean_e1(const Sums& s) { return s.e1 / s.n; }
double mean_e2(const Sums& s) { return s.e2 / s.n; }

// The composed estimator's factor 1 - |g|^2 for the first-order shear (a1, a2) = <e> / R: the fixed
// point of g = a (1 - |g|^2), converging in a few steps for |g| << 1.
double composition_factor(double a1, double a2) {
  double k = 1;
  for (int i = 0; i < 8; ++i) k = 1 - k * k * (a1 * a1 + a2 * a2);
  return k;
}

std::array<double, 4> response_and_shear(const std::array<Sums, 5>& p, double step, MetadetectEstimator estimator) {
  const double r11 = (mean_e1(p[1]) - mean_e1(p[2])) / (2 * step);
  const double r22 = (mean_e2(p[3]) - mean_e2(p[4])) / (2 * step);
  const double a1 = mean_e1(p[0]) / r11, a2 = mean_e2(p[0]) / r22;
  const double k = estimator == MetadetectEstimator::kComposed ? composition_factor(a1, a2) : 1.0;
  return {r11, r22, a1 * k, a2 * k};
}

}  // namespace

const char* metadetect_estimator_name(MetadetectEstimator e) {
  return e == MetadetectEstimator::kComposed ? "composed" : "package";
}

bool parse_metadetect_estimator(const std::string& name, MetadetectEstimator* out) {
  std::string s = name;
  for (char& c : s) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  for (MetadetectEstimator e : {MetadetectEstimator::kComposed, MetadetectEstimator::kPackage})
    if (s == metadetect_estimator_name(e)) {
      *out = e;
      return true;
    }
  return false;
}

MetadetectCellSums sum_metadetect_cells(const std::vector<long long>& cell, const std::vector<int>& shear_type,
                                        const std::vector<double>& e1, const std::vector<double>& e2,
                                        const std::vector<long long>& flags, const std::vector<double>& snr,
                                        const std::vector<double>& t_ratio, const std::vector<double>& mfrac,
                                        const MetadetectCuts& cuts) {
  std::map<long long, std::array<Sums, 5>> by_cell;
  for (std::size_t i = 0; i < cell.size(); ++i) {
    std::array<Sums, 5>& c = by_cell[cell[i]];
    const int t = shear_type[i];
    if (t < 0 || t >= 5) continue;
    if ((static_cast<std::uint64_t>(flags[i]) & cuts.excluded_flags) != 0) continue;
    if (!(snr[i] > cuts.min_snr) || !(t_ratio[i] > cuts.min_t_ratio) || !(mfrac[i] <= cuts.max_mfrac)) continue;
    if (!std::isfinite(e1[i]) || !std::isfinite(e2[i])) continue;
    c[t].n += 1, c[t].e1 += e1[i], c[t].e2 += e2[i];
  }
  MetadetectCellSums out;
  for (const auto& [k, s] : by_cell) out.cells.push_back(k), out.sums.push_back(s);
  return out;
}

void add_cell_sums(const MetadetectCellSums& more, MetadetectCellSums* into) {
  if (more.cells != into->cells) throw std::invalid_argument("the catalogues do not hold the same cells");
  for (std::size_t k = 0; k < more.sums.size(); ++k)
    for (int t = 0; t < 5; ++t) {
      into->sums[k][t].n += more.sums[k][t].n;
      into->sums[k][t].e1 += more.sums[k][t].e1;
      into->sums[k][t].e2 += more.sums[k][t].e2;
    }
}

MetadetectShear metadetect_shear(const MetadetectCellSums& s, double step, int resamples, std::uint64_t seed,
                                 MetadetectEstimator estimator) {
  MetadetectShear out;
  const std::array<Sums, 5> p = pooled(s, {});
  const std::array<double, 4> v = response_and_shear(p, step, estimator);
  out.r11 = v[0], out.r22 = v[1], out.g1 = v[2], out.g2 = v[3];
  out.cells = static_cast<long long>(s.cells.size());
  out.kept_noshear = p[0].n;
  std::vector<int> count(s.cells.size());
  const std::array<double, 4> err =
      bootstrap_errors<4>(&count, resamples, seed, [&](const std::vector<int>& c) {
        return response_and_shear(pooled(s, c), step, estimator);
      });
  out.r11_err = err[0], out.r22_err = err[1], out.g1_err = err[2], out.g2_err = err[3];
  return out;
}

MetadetectBias metadetect_pair_bias(const MetadetectCellSums& plus, const MetadetectCellSums& minus, double g1,
                                    double g2, double step, int resamples, std::uint64_t seed,
                                    MetadetectEstimator estimator) {
  if (plus.cells != minus.cells)
    throw std::invalid_argument("the two catalogues do not hold the same cells: they are not a shear pair");
  if (g1 == 0 && g2 == 0) throw std::invalid_argument("the true shear is zero: m is undefined");
  auto estimate = [&](const std::vector<int>& c) -> std::array<double, 4> {
    const std::array<Sums, 5> p = pooled(plus, c), q = pooled(minus, c);
    const double r11 = 0.5 * ((mean_e1(p[1]) - mean_e1(p[2])) + (mean_e1(q[1]) - mean_e1(q[2]))) / (2 * step);
    const double r22 = 0.5 * ((mean_e2(p[3]) - mean_e2(p[4])) + (mean_e2(q[3]) - mean_e2(q[4]))) / (2 * step);
    const double d1 = 0.5 * (mean_e1(p[0]) - mean_e1(q[0])), s1 = 0.5 * (mean_e1(p[0]) + mean_e1(q[0]));
    const double d2 = 0.5 * (mean_e2(p[0]) - mean_e2(q[0])), s2 = 0.5 * (mean_e2(p[0]) + mean_e2(q[0]));
    // The pair's shear read from its half difference; c from the half sum, where the composition's
    // factor is 1 to second order in c.
    const double k = estimator == MetadetectEstimator::kComposed ? composition_factor(d1 / r11, d2 / r22) : 1.0;
    return {g1 != 0 ? k * d1 / r11 / g1 - 1 : NAN, s2 / r22, g2 != 0 ? k * d2 / r22 / g2 - 1 : NAN, s1 / r11};
  };
  MetadetectBias out;
  const std::array<double, 4> v = estimate({});
  out.m1 = v[0], out.c2 = v[1], out.m2 = v[2], out.c1 = v[3];
  out.pairs = static_cast<long long>(plus.cells.size());
  std::vector<int> count(plus.cells.size());
  // bootstrap_errors skips draws with a non-finite statistic: NaN components are bootstrapped apart.
  const std::array<double, 4> err = bootstrap_errors<4>(&count, resamples, seed, [&](const std::vector<int>& c) {
    std::array<double, 4> q = estimate(c);
    for (double& x : q)
      if (std::isnan(x)) x = 0;
    return q;
  });
  out.m1_err = g1 != 0 ? err[0] : NAN, out.c2_err = err[1], out.m2_err = g2 != 0 ? err[2] : NAN, out.c1_err = err[3];
  return out;
}

}  // namespace stampede
