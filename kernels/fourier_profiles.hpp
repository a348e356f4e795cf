// Two-dimensional Fourier transforms of the radial profiles the simulator draws, for unit flux:
//   F(k) = 2 pi Integral_0^inf I(r) J0(k r) r dr / flux,   F(0) = 1.
// Drawing in Fourier space avoids sampling cusps on a grid: the only errors left are the
// tabulation and the real-space period of the final inverse transform.
#pragma once

#include <functional>
#include <vector>

namespace stampede::kernels {

// Sérsic index n, unit half-light radius, at wavenumber q (radians per half-light radius), by
// quadrature over the Gamma(2n) variable u = b_n r^(1/n) in panels of at most 2 pi in the Bessel
// phase, stopped where the rest of the light or of the decaying oscillation is below 1e-12 of
// F(0). Costs ~1e5 Bessel evaluations at q ~ 300 for n = 4. Accurate for n >= 1 (the u^(2n-1)
// weight is smooth there).
double sersic_fourier(double n, double q);
// Exponential (n = 1) in closed form at q (per half-light radius): (1 + (q / b_1)^2)^(-3/2).
double exponential_fourier(double q);
// Mean r^2 over a unit-flux Sérsic of unit half-light radius: Gamma(4n) / (Gamma(2n) b_n^(2n)).
double sersic_mean_r2(double n);

// Moffat (1 + (r/alpha)^2)^-beta at x = k alpha. Untruncated (truncation_over_alpha = 0):
// 2^(2-beta) / Gamma(beta-1) x^(beta-1) K_(beta-1)(x), beta > 1. Truncated at r = T alpha:
// quadrature over [0, T].
double moffat_fourier(double beta, double truncation_over_alpha, double x);
// Unobscured Airy disc (circular pupil) at s = k lambda/D / (2 pi), the optical transfer function
// (2/pi)(acos s - s sqrt(1 - s^2)) for s < 1, zero beyond.
double airy_fourier(double s);

// Log-spaced nodes q_i = q_min 10^(i / nodes_per_decade), i = 0 .. count - 1, covering q_max.
struct LogGrid {
  double q_min = 1e-4;
  int nodes_per_decade = 40;
  int count = 0;
  static LogGrid covering(double q_min, double q_max, int nodes_per_decade);
  double node(int i) const;
};

// A smooth function of q >= 0 tabulated on a LogGrid and interpolated by six-point Lagrange in
// log q. Below q_min: 1 - c2 q^2, the Taylor series at 0 of a unit-flux transform, with
// c2 = (1 - f(q_min)) / q_min^2. Above the last node: the power law through the last two nodes
// (or 0 when they change sign or vanish).
class LogTable {
 public:
  LogTable() = default;
  // values[i] = f(grid.node(i)); callers may compute them in parallel.
  LogTable(const LogGrid& grid, std::vector<double> values);
  LogTable(const std::function<double(double)>& f, const LogGrid& grid);
  double operator()(double q) const;
  double q_max() const { return q_max_; }

 private:
  static constexpr int kPoints = 6;
  double q_min_ = 0, q_max_ = 0, log_q_min_ = 0, inv_step_ = 0, c2_ = 0;
  double tail_log_slope_ = 0, tail_value_ = 0;
  std::vector<double> values_;
};

}  // namespace stampede::kernels
