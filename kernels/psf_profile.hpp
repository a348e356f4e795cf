// Analytic PSF profiles sampled on a periodic sub-pixel lag grid (lag 0 at index 0, wrapped), the
// layout a circular FFT convolution expects. Values are flux per sub-pixel (intensity * step^2),
// profiles normalised analytically to unit total flux, so the sampled sum is a real check of the
// sampling rather than a normalisation by construction.
#pragma once

namespace stampede::kernels {

// Moffat: I(r) = (beta - 1) / (pi alpha^2) (1 + (r/alpha)^2)^-beta, alpha = fwhm / (2 sqrt(2^(1/beta) - 1)),
// sheared by (e1, e2) (area-preserving, reduced-shear convention), optionally truncated at
// `truncation` (radius in the unsheared frame, pixels; 0 = none) and renormalised to unit flux.
struct MoffatProfile {
  double beta = 3.0;
  double fwhm = 2.85;
  double e1 = 0.0;
  double e2 = 0.0;
  double truncation = 0.0;
};

// Airy disc with central obscuration eps (0 <= eps < 1) and lambda/D given in pixels:
// I(r) = pi / (4 L^2 (1 - eps^2)) [2 J1(x)/x - eps^2 2 J1(eps x)/(eps x)]^2,  x = pi r / L.
struct AiryProfile {
  double lambda_over_d = 2.0;
  double obscuration = 0.0;
};

// Gaussian: I(r) = exp(-r^2 / (2 sigma^2)) / (2 pi sigma^2), sigma = fwhm / 2.3548, sheared by
// (e1, e2) as the Moffat is. Its transform is exp(-sigma^2 |S k|^2 / 2): it falls faster than any
// PSF with a Moffat-like or Gaussian core, which is why metacalibration reconvolves with it.
struct GaussianProfile {
  double fwhm = 2.0;
  double e1 = 0.0;
  double e2 = 0.0;
};

double moffat_alpha(double fwhm, double beta);
double gaussian_sigma(double fwhm);
double moffat_intensity(const MoffatProfile& psf, double dx, double dy);
double airy_intensity(const AiryProfile& psf, double dx, double dy);
double gaussian_intensity(const GaussianProfile& psf, double dx, double dy);

// Fills out[n*n] with the profile at lags ((i < (n+1)/2 ? i : i - n) * step), row-major.
void sample_moffat_wrapped(const MoffatProfile& psf, int n, double step, double* out);
void sample_airy_wrapped(const AiryProfile& psf, int n, double step, double* out);

}  // namespace stampede::kernels
