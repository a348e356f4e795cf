// Sérsic constants; see sersic.hpp.
#include "kernels/sersic.hpp"

#include <math.h>

#include <cmath>
#include <numbers>

namespace stampede::kernels {
namespace {

// std::lgamma writes the global `signgam`: a data race when fits run on several threads (found by
// ThreadSanitizer). lgamma_r is the reentrant form.
double log_gamma(double x) {
  int sign = 0;
  return ::lgamma_r(x, &sign);
}

// Series expansion, converges quickly for x < a + 1.
double gamma_p_series(double a, double x) {
  double term = 1.0 / a;
  double sum = term;
  for (int k = 1; k < 1000; ++k) {
    term *= x / (a + k);
    sum += term;
    if (std::abs(term) < std::abs(sum) * 1e-17) break;
  }
  return sum * std::exp(-x + a * std::log(x) - log_gamma(a));
}

// Lentz continued fraction for Q(a, x) = 1 - P(a, x), converges for x >= a + 1.
double gamma_q_continued_fraction(double a, double x) {
  constexpr double tiny = 1e-300;
  double b = x + 1.0 - a;
  double c = 1.0 / tiny;
  double d = 1.0 / b;
  double h = d;
  for (int i = 1; i < 1000; ++i) {
    const double an = -i * (i - a);
    b += 2.0;
    d = an * d + b;
    if (std::abs(d) < tiny) d = tiny;
    c = b + an / c;
    if (std::abs(c) < tiny) c = tiny;
    d = 1.0 / d;
    const double delta = d * c;
    h *= delta;
    if (std::abs(delta - 1.0) < 1e-16) break;
  }
  return std::exp(-x + a * std::log(x) - log_gamma(a)) * h;
}

}  // namespace

double regularized_gamma_p(double a, double x) {
  if (x <= 0.0) return 0.0;
  if (x < a + 1.0) return gamma_p_series(a, x);
  return 1.0 - gamma_q_continued_fraction(a, x);
}

double solve_sersic_b(double n) {
  const double a = 2.0 * n;
  // Ciotti & Bertin (1999) asymptotic expansion as the starting guess, then Newton on P(2n, b) = 1/2
  // (dP/db = b^(a-1) e^-b / Gamma(a)).
  double b = 2.0 * n - 1.0 / 3.0 + 4.0 / (405.0 * n) + 46.0 / (25515.0 * n * n);
  if (b <= 0.0) b = 0.1;
  for (int it = 0; it < 50; ++it) {
    const double f = regularized_gamma_p(a, b) - 0.5;
    const double df = std::exp((a - 1.0) * std::log(b) - b - log_gamma(a));
    const double step = f / df;
    b -= step;
    if (b <= 0.0) b = 1e-6;
    if (std::abs(step) < 1e-15 * b) break;
  }
  return b;
}

double sersic_b(double n) {
  // The model's two fixed indices are solved once (thread-safe static initialisation, immutable).
  static const double b1 = solve_sersic_b(1.0), b4 = solve_sersic_b(4.0);
  if (n == 1.0) return b1;
  if (n == 4.0) return b4;
  return solve_sersic_b(n);
}

double sersic_flux_per_amplitude(double half_light_radius, double n) {
  const double b = sersic_b(n);
  return 2.0 * std::numbers::pi * n * std::exp(log_gamma(2.0 * n) - 2.0 * n * std::log(b)) *
         half_light_radius * half_light_radius;
}

double sersic_flux(double amplitude, double half_light_radius, double n) {
  return amplitude * sersic_flux_per_amplitude(half_light_radius, n);
}

}  // namespace stampede::kernels
