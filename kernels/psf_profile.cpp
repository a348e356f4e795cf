// Analytic PSF profiles; see psf_profile.hpp.
#include "kernels/psf_profile.hpp"

#include <cmath>
#include <numbers>

#include "kernels/ellipse.hpp"

namespace stampede::kernels {
namespace {

inline int wrapped_lag(int i, int n) { return i < (n + 1) / 2 ? i : i - n; }

struct MoffatPrecomputed {
  EllipseQuadratic q;  // (r / alpha)^2 in the sheared frame
  double norm;
  double beta;
  double u_max;  // (truncation / alpha)^2, or +inf
  explicit MoffatPrecomputed(const MoffatProfile& p) : beta(p.beta) {
    const double alpha = moffat_alpha(p.fwhm, p.beta);
    q = ellipse_quadratic(p.e1, p.e2, alpha);
    double flux_inside = 1.0;
    u_max = INFINITY;
    if (p.truncation > 0.0) {
      u_max = (p.truncation / alpha) * (p.truncation / alpha);
      flux_inside = 1.0 - std::pow(1.0 + u_max, 1.0 - p.beta);
    }
    norm = (p.beta - 1.0) / (std::numbers::pi * alpha * alpha) / flux_inside;
  }
  double operator()(double dx, double dy) const {
    const double u = q(dx, dy);
    return u > u_max ? 0.0 : norm * std::pow(1.0 + u, -beta);
  }
};

struct AiryPrecomputed {
  double x_per_r;
  double norm;
  double eps;
  explicit AiryPrecomputed(const AiryProfile& p)
      : x_per_r(std::numbers::pi / p.lambda_over_d),
        norm(std::numbers::pi / (4.0 * p.lambda_over_d * p.lambda_over_d * (1.0 - p.obscuration * p.obscuration))),
        eps(p.obscuration) {}
  double operator()(double dx, double dy) const {
    const double x = x_per_r * std::sqrt(dx * dx + dy * dy);
    double amp;
    if (x < 1e-8) {
      amp = 1.0 - eps * eps;
    } else {
      amp = 2.0 * std::cyl_bessel_j(1.0, x) / x;
      if (eps > 0.0) amp -= eps * eps * 2.0 * std::cyl_bessel_j(1.0, eps * x) / (eps * x);
    }
    return norm * amp * amp;
  }
};

template <class Profile>
void sample_wrapped(const Profile& profile, int n, double step, double* out) {
  const double area = step * step;
  for (int j = 0; j < n; ++j) {
    const double dy = wrapped_lag(j, n) * step;
    for (int i = 0; i < n; ++i) out[j * n + i] = area * profile(wrapped_lag(i, n) * step, dy);
  }
}

}  // namespace

double moffat_alpha(double fwhm, double beta) { return fwhm / (2.0 * std::sqrt(std::pow(2.0, 1.0 / beta) - 1.0)); }

double moffat_intensity(const MoffatProfile& psf, double dx, double dy) { return MoffatPrecomputed(psf)(dx, dy); }

double gaussian_sigma(double fwhm) { return fwhm / 2.3548200450309493; }

double gaussian_intensity(const GaussianProfile& psf, double dx, double dy) {
  // I(x) = f(x^T Q x), det Q = 1, with f the round profile of sigma.
  const EllipseQuadratic q = ellipse_quadratic(psf.e1, psf.e2, 1.0);
  const double s2 = gaussian_sigma(psf.fwhm) * gaussian_sigma(psf.fwhm);
  const double r2 = q.xx * dx * dx + 2.0 * q.xy * dx * dy + q.yy * dy * dy;
  return std::exp(-0.5 * r2 / s2) / (2.0 * std::numbers::pi * s2);
}

double airy_intensity(const AiryProfile& psf, double dx, double dy) { return AiryPrecomputed(psf)(dx, dy); }

void sample_moffat_wrapped(const MoffatProfile& psf, int n, double step, double* out) {
  sample_wrapped(MoffatPrecomputed(psf), n, step, out);
}

void sample_airy_wrapped(const AiryProfile& psf, int n, double step, double* out) {
  sample_wrapped(AiryPrecomputed(psf), n, step, out);
}

}  // namespace stampede::kernels
