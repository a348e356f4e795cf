// Fourier transforms of radial profiles; see fourier_profiles.hpp.
#include "kernels/fourier_profiles.hpp"

#include <math.h>  // j0: glibc's is far faster than std::cyl_bessel_j, as accurate (docs/performance.md)

#include <algorithm>
#include <cmath>
#include <numbers>
#include <stdexcept>

#include "kernels/math/gauss_legendre.hpp"
#include "kernels/sersic.hpp"

namespace stampede::kernels {
namespace {

constexpr double kPi = std::numbers::pi;

double log_gamma(double x) {
  int sign = 0;
  return ::lgamma_r(x, &sign);  // reentrant: the tables may be built on several threads
}

}  // namespace

double exponential_fourier(double q) {
  const double s = q / sersic_b(1.0);
  const double t = 1.0 + s * s;
  return 1.0 / (t * std::sqrt(t));
}

double sersic_mean_r2(double n) {
  return std::exp(log_gamma(4 * n) - log_gamma(2 * n) - 2 * n * std::log(sersic_b(n)));
}

double sersic_fourier(double n, double q) {
  if (q == 0.0) return 1.0;
  const double b = sersic_b(n), a = 2 * n, lg = log_gamma(a);
  // u = b r^(1/n) is Gamma(2n)-distributed over the profile's light; r = (u / b)^n.
  auto weight = [&](double u) { return u > 0 ? std::exp(-u + (a - 1) * std::log(u) - lg) : 0.0; };
  auto phase = [&](double u) { return q * std::pow(u / b, n); };
  auto u_at_phase = [&](double p) { return b * std::pow(p / q, 1.0 / n); };
  const GaussLegendre12& gl = gauss_legendre_12();
  constexpr double kMaxPanel = 0.5;  // resolves the Gamma density
  constexpr double kTolerance = 1e-12;  // absolute, on F(0) = 1
  double sum = 0, u = 0;
  long long next_phase_step = 1;
  for (long long panel = 0; panel < 50'000'000; ++panel) {
    double end = u + kMaxPanel;
    // Panels span 2 pi of Bessel phase: 12-point Gauss-Legendre is exact there to ~1e-12.
    const double u_phase = u_at_phase(2 * kPi * static_cast<double>(next_phase_step));
    bool at_phase_boundary = false;
    if (u_phase <= end) {
      end = u_phase;
      ++next_phase_step;
      at_phase_boundary = true;
    }
    sum += gl.integrate(u, end, [&](double t) { return weight(t) * ::j0(phase(t)); });
    u = end;
    if (u <= a + 1) continue;  // still before the peak of the light
    const double w = weight(u);
    // Remaining light (Gamma tail, bounded by w u / (u - a + 1)), or, past a full half period of
    // an oscillation with decaying amplitude, the size of the next half period.
    if (w * u / (u - a + 1) < kTolerance) break;
    if (at_phase_boundary) {
      const double p = phase(u), dphase = n * p / u;
      const double envelope = std::min(1.0, std::sqrt(2 / (kPi * p)));
      if (w * envelope * kPi / dphase < kTolerance) break;
    }
  }
  return sum;
}

double moffat_fourier(double beta, double truncation_over_alpha, double x) {
  if (!(beta > 1.0)) throw std::invalid_argument("moffat_fourier: beta must exceed 1");
  if (truncation_over_alpha <= 0.0) {
    if (x < 1e-10) return 1.0;
    const double nu = beta - 1;
    return std::exp((2 - beta) * std::numbers::ln2 - log_gamma(nu) + nu * std::log(x)) * std::cyl_bessel_k(nu, x);
  }
  const double t = truncation_over_alpha;
  const double norm = (1 - std::pow(1 + t * t, 1 - beta)) / (2 * (beta - 1));
  const double panel = x > 0 ? std::min(0.25, kPi / x) : 0.25;
  const GaussLegendre12& gl = gauss_legendre_12();
  double sum = 0;
  for (double r = 0; r < t; r += panel) {
    sum += gl.integrate(r, std::min(t, r + panel),
                        [&](double s) { return std::pow(1 + s * s, -beta) * ::j0(x * s) * s; });
  }
  return sum / norm;
}

double airy_fourier(double s) {
  if (s >= 1.0) return 0.0;
  return 2 / kPi * (std::acos(s) - s * std::sqrt(1 - s * s));
}

LogGrid LogGrid::covering(double q_min, double q_max, int nodes_per_decade) {
  LogGrid g;
  g.q_min = q_min;
  g.nodes_per_decade = nodes_per_decade;
  g.count = std::max(6, static_cast<int>(std::ceil(std::log10(q_max / q_min) * nodes_per_decade)) + 1);
  return g;
}

double LogGrid::node(int i) const { return q_min * std::pow(10.0, static_cast<double>(i) / nodes_per_decade); }

LogTable::LogTable(const std::function<double(double)>& f, const LogGrid& grid)
    : LogTable(grid, [&] {
        std::vector<double> v(static_cast<std::size_t>(grid.count));
        for (int i = 0; i < grid.count; ++i) v[static_cast<std::size_t>(i)] = f(grid.node(i));
        return v;
      }()) {}

LogTable::LogTable(const LogGrid& grid, std::vector<double> values)
    : q_min_(grid.q_min), log_q_min_(std::log(grid.q_min)), values_(std::move(values)) {
  const int count = static_cast<int>(values_.size());
  if (count < kPoints || count != grid.count) throw std::invalid_argument("LogTable: values do not match the grid");
  inv_step_ = grid.nodes_per_decade / std::numbers::ln10;
  q_max_ = grid.node(count - 1);
  c2_ = (1 - values_[0]) / (q_min_ * q_min_);
  const double last = values_[count - 1], before = values_[count - 2];
  tail_value_ = 0;
  if (last != 0 && before != 0 && (last > 0) == (before > 0)) {
    tail_value_ = last;
    tail_log_slope_ = std::log(last / before) * inv_step_;
  }
}

double LogTable::operator()(double q) const {
  if (q < q_min_) return 1.0 - c2_ * q * q;
  if (q >= q_max_) return tail_value_ * std::pow(q / q_max_, tail_log_slope_);
  const double t = (std::log(q) - log_q_min_) * inv_step_;
  const int last_start = static_cast<int>(values_.size()) - kPoints;
  const int i = std::clamp(static_cast<int>(t) - (kPoints / 2 - 1), 0, last_start);
  const double s = t - i;  // position among nodes i .. i + kPoints - 1 at 0 .. kPoints - 1
  // Lagrange weights l_j = prod_{m != j} (s - m) / prod_{m != j} (j - m), by prefix and suffix
  // products; the denominators are those of six equally spaced nodes.
  static_assert(kPoints == 6);
  constexpr double kInvDenominator[6] = {-1.0 / 120, 1.0 / 24, -1.0 / 12, 1.0 / 12, -1.0 / 24, 1.0 / 120};
  double prefix[kPoints], suffix[kPoints];
  prefix[0] = 1;
  for (int j = 1; j < kPoints; ++j) prefix[j] = prefix[j - 1] * (s - (j - 1));
  suffix[kPoints - 1] = 1;
  for (int j = kPoints - 2; j >= 0; --j) suffix[j] = suffix[j + 1] * (s - (j + 1));
  const double* v = values_.data() + i;
  double sum = 0;
  for (int j = 0; j < kPoints; ++j) sum += prefix[j] * suffix[j] * kInvDenominator[j] * v[j];
  return sum;
}

}  // namespace stampede::kernels
