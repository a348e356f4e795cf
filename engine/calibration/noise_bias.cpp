// The noise-bias model; see noise_bias.hpp.
#include "engine/calibration/noise_bias.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>

#include "engine/common/number_text.hpp"
#include "engine/common/random_stream.hpp"
#include "kernels/polynomial_fit.hpp"

namespace stampede {
namespace {

constexpr int kCurvesPerNode = 4;  // (axis e1, comp 0), (e1, 1), (e2, 0), (e2, 1)
constexpr int kOutputs = kCurvesPerNode * 4;

int curve_slot(BiasAxis axis, int component) { return 2 * static_cast<int>(axis) + component; }

}  // namespace

std::vector<BiasCurve> fit_bias_curves(const CalibrationGridOptions& grid, const std::vector<CalibrationPoint>& points,
                                       const std::vector<PointBias>& biases) {
  if (points.size() != biases.size()) throw std::invalid_argument("fit_bias_curves: one bias per point needed");
  std::vector<BiasCurve> curves;
  for (double r : grid.radii)
    for (double f : grid.bulge_fractions)
      for (BiasAxis axis : {BiasAxis::kE1, BiasAxis::kE2})
        for (int c = 0; c < 2; ++c) {
          std::vector<double> x, y, w;
          for (std::size_t i = 0; i < points.size(); ++i) {
            const CalibrationPoint& p = points[i];
            if (p.radius != r || p.bulge_fraction != f || p.axis != axis) continue;
            const PointBias& b = biases[i];
            if (!std::isfinite(b.bias[c]) || !(b.error[c] > 0)) continue;
            x.push_back(p.e_true);
            y.push_back(b.bias[c]);
            w.push_back(1.0 / (b.error[c] * b.error[c]));
          }
          BiasCurve curve;
          curve.radius = r;
          curve.bulge_fraction = f;
          curve.axis = axis;
          curve.component = c;
          curve.points = static_cast<int>(x.size());
          curve.coefficients.fill(NAN);
          curve.errors.fill(NAN);
          if (x.size() >= 4) {
            const kernels::PolynomialFit fit = kernels::fit_polynomial(x, y, w, 3);
            if (fit.ok()) {
              std::copy_n(fit.coefficients.begin(), 4, curve.coefficients.begin());
              std::copy_n(fit.errors.begin(), 4, curve.errors.begin());
              curve.chi2 = fit.chi2;
            }
          }
          curves.push_back(curve);
        }
  return curves;
}

NoiseBiasModel::NoiseBiasModel(const CalibrationTable& table) {
  const CalibrationGridOptions& g = table.grid;
  const std::size_t nodes = g.radii.size() * g.bulge_fractions.size();
  if (nodes == 0 || table.curves.size() != nodes * kCurvesPerNode)
    throw std::invalid_argument("calibration table: expected " + std::to_string(nodes * kCurvesPerNode) +
                                " bias curves, found " + std::to_string(table.curves.size()));
  // Curves come radius by radius, each radius's fractions in order: the spline's node order.
  std::vector<double> values(nodes * kOutputs, NAN);
  for (std::size_t n = 0; n < nodes; ++n) {
    const BiasCurve& first = table.curves[n * kCurvesPerNode];
    if (first.radius != g.radii[n / g.bulge_fractions.size()] ||
        first.bulge_fraction != g.bulge_fractions[n % g.bulge_fractions.size()])
      throw std::invalid_argument("calibration table: bias curves out of order at row " +
                                  std::to_string(n * kCurvesPerNode));
    for (int k = 0; k < kCurvesPerNode; ++k) {
      const BiasCurve& c = table.curves[n * kCurvesPerNode + k];
      if (c.radius != first.radius || c.bulge_fraction != first.bulge_fraction ||
          curve_slot(c.axis, c.component) != k)
        throw std::invalid_argument("calibration table: bias curves out of order at row " +
                                    std::to_string(n * kCurvesPerNode + k));
      for (int j = 0; j < 4; ++j) {
        if (!std::isfinite(c.coefficients[j]))
          throw std::invalid_argument("calibration table: no bias curve at r_d = " + std::to_string(c.radius) +
                                      ", F = " + number_text(c.bulge_fraction) + " (too few usable fits)");
        values[n * kOutputs + 4 * k + j] = c.coefficients[j];
      }
    }
  }
  std::vector<double> ln_radii;
  for (double r : g.radii) ln_radii.push_back(std::log(r));
  spline_ = kernels::TensorSpline(ln_radii, g.bulge_fractions, values, kOutputs);
  if (!spline_.ok())
    throw std::invalid_argument("calibration table: radii and bulge fractions must be increasing, at most " +
                                std::to_string(kernels::kMaxSplineNodes) + " of each");
  ln_r_min_ = std::log(g.radii.front());
  ln_r_max_ = std::log(g.radii.back());
  f_min_ = g.bulge_fractions.front();
  f_max_ = g.bulge_fractions.back();
  e_max_ = g.e_max;
  snr_ref_ = g.snr;
  if (g.psf.kind == PsfKind::kMoffat) psf_e0_ = {g.psf.moffat.e1, g.psf.moffat.e2};
}

Bias NoiseBiasModel::at(const GalaxyProperties& galaxy, bool* clamped) const {
  const double ln_r = std::log(std::max(galaxy.radius, 1e-300));
  const double x[2] = {std::clamp(ln_r, ln_r_min_, ln_r_max_), std::clamp(galaxy.bulge_fraction, f_min_, f_max_)};
  const double e = std::min(std::abs(galaxy.e), e_max_);
  if (clamped) *clamped = x[0] != ln_r || x[1] != galaxy.bulge_fraction || e != std::abs(galaxy.e);
  double a[kOutputs];
  spline_.evaluate(x[0], x[1], a);
  const auto coeff = [&](BiasAxis axis, int comp, int j) { return a[4 * curve_slot(axis, comp) + j]; };
  const double e2 = e * e;
  const auto slope = [&](BiasAxis axis, int comp) {
    return coeff(axis, comp, 1) + coeff(axis, comp, 3) * e2 * (2 - e2);
  };
  const auto even = [&](BiasAxis axis, int comp) { return coeff(axis, comp, 0) + coeff(axis, comp, 2) * e2; };
  Bias b;
  b.m = 0.5 * (slope(BiasAxis::kE1, 0) + slope(BiasAxis::kE2, 1));
  b.c1 = 0.5 * (even(BiasAxis::kE1, 0) + even(BiasAxis::kE2, 0));
  b.c2 = 0.5 * (even(BiasAxis::kE1, 1) + even(BiasAxis::kE2, 1));
  // By symmetry the additive bias lies along the PSF: keep that component (appendix C's scalar
  // c_hat) and drop the cross one, which is noise.
  if (std::abs(psf_e0_) > 1e-12) {
    const std::complex<double> axis = psf_e0_ / std::abs(psf_e0_);
    const std::complex<double> along = std::real(std::complex<double>(b.c1, b.c2) * std::conj(axis)) * axis;
    b.c1 = along.real();
    b.c2 = along.imag();
  }
  return b;
}

void PopulationBias::add(const GalaxyProperties& galaxy) {
  bool clamped = false;
  const Bias b = model_.at(galaxy, &clamped);
  ++n_;
  clamped_ += clamped;
  sum_m_ += b.m;
  sum_c1_ += b.c1;
  sum_c2_ += b.c2;
}

Bias PopulationBias::mean() const {
  if (n_ == 0) return {NAN, NAN, NAN};
  return {sum_m_ / n_, sum_c1_ / n_, sum_c2_ / n_};
}

Bias population_bias_error(const CalibrationTable& table, const std::vector<GalaxyProperties>& sample, int resamples,
                           std::uint64_t seed) {
  if (sample.empty() || resamples < 2) return {NAN, NAN, NAN};
  double s[3] = {0, 0, 0}, s2[3] = {0, 0, 0};
  CalibrationTable redrawn = table;
  for (int k = 0; k < resamples; ++k) {
    RandomStream rng({seed, static_cast<std::uint64_t>(k)});
    for (std::size_t i = 0; i < table.biases.size(); ++i)
      for (int c = 0; c < 2; ++c) {
        const PointBias& b = table.biases[i];
        redrawn.biases[i].bias[c] = std::isfinite(b.error[c]) ? b.bias[c] + b.error[c] * rng.normal() : b.bias[c];
      }
    redrawn.curves = fit_bias_curves(redrawn.grid, redrawn.points, redrawn.biases);
    const NoiseBiasModel model(redrawn);
    PopulationBias pop(model);
    for (const GalaxyProperties& g : sample) pop.add(g);
    const Bias mean = pop.mean();
    const double v[3] = {mean.m, mean.c1, mean.c2};
    for (int j = 0; j < 3; ++j) {
      s[j] += v[j];
      s2[j] += v[j] * v[j];
    }
  }
  double sd[3];
  for (int j = 0; j < 3; ++j) {
    const double mean = s[j] / resamples;
    sd[j] = std::sqrt(std::max(0.0, (s2[j] / resamples - mean * mean) * resamples / (resamples - 1)));
  }
  return {sd[0], sd[1], sd[2]};
}

Bias object_correction(const Bias& bias, double snr_ref, std::complex<double> psf_e0, double snr,
                       std::complex<double> psf_e) {
  if (!(snr > 0) || !std::isfinite(snr)) return {NAN, NAN, NAN};
  const double scale = (snr_ref / snr) * (snr_ref / snr);
  std::complex<double> c(bias.c1, bias.c2);
  if (std::abs(psf_e0) > 1e-12 && std::isfinite(psf_e.real()) && std::isfinite(psf_e.imag())) c *= psf_e / psf_e0;
  return {bias.m * scale, c.real() * scale, c.imag() * scale};
}

}  // namespace stampede
