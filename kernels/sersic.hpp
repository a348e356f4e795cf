// Sérsic profile constants: the exact half-light b_n and the analytic total flux.
//   I(r) = A exp(-b_n (r / r_e)^(1/n)),  flux = 2 pi n Gamma(2n) A r_e^2 / b_n^(2n).
#pragma once

namespace stampede::kernels {

// Regularised lower incomplete gamma P(a, x) = gamma(a, x) / Gamma(a), a > 0, x >= 0.
double regularized_gamma_p(double a, double x);

// b_n such that r_e encloses half the flux of the infinite profile: P(2n, b_n) = 1/2.
// Valid for 0.2 <= n <= 10 (b_1 = 1.678347.., b_4 = 7.669249..).
double sersic_b(double n);
// The same, always solved (sersic_b caches n = 1 and n = 4).
double solve_sersic_b(double n);

// Total flux of the infinite profile with central intensity `amplitude` (flux / pixel^2).
// An area-preserving shear does not change it.
double sersic_flux(double amplitude, double half_light_radius, double n);

// d(flux)/d(amplitude) at unit amplitude: flux = amplitude * sersic_flux_per_amplitude.
double sersic_flux_per_amplitude(double half_light_radius, double n);

}  // namespace stampede::kernels
