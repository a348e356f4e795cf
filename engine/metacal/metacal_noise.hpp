// The noise metacal's images carry, for their errors and S/N. The data's noise (variance sigma^2
// per pixel) goes through the noshear operator, diagonal in Fourier space: its power spectrum
// becomes sigma^2 |f(k)|^2, correlated over Gamma's width. Fixnoise adds an independent field of
// the same variance through the same operator rotated by 90 degrees: sigma^2 |f(R k)|^2. So an
// image's noise N has the stationary covariance of power
//   P(k) = sigma^2 (|f(k)|^2 + |f(R k)|^2),
// and any linear combination of its pixels has Var(sum_p a_p N_p) = sum_k |a~(k)|^2 P(k) / M^2 on
// the M x M grid, which the white-noise formula sigma_img^2 sum a_p^2 (sigma_img^2 = mean P, the
// per-pixel variance) underestimates by the factor P(k) at a's frequencies over its mean: ~1.3 for
// the default Gamma's wmom, ~16 for metacal_psf_dilation 1.5 (docs/metacal.md, "Errors and S/N").
// The sheared images' noise differs from the noshear one's by O(step); they are given the noshear
// image's, so that every image is measured by one function of its pixels (selection responses).
// The data's per-pixel variance is its mean over the stamp, and the noise is taken as periodic on
// the grid (the stamp's zero padding carries none: near its edge the variance is overstated).
#pragma once

#include <span>
#include <vector>

#include "engine/common/fftw_support.hpp"
#include "engine/fit/fit_result.hpp"
#include "engine/metacal/metacal_filters.hpp"
#include "kernels/weighted_moments.hpp"

namespace stampede {

// The images' noise power for data of mean per-pixel variance `input_variance` through `filters`
// (with fixnoise's field when `fixnoise`), on filters' M x (M/2 + 1) half spectrum in FFTW's r2c
// layout, each column that stands for two (0 < c < M/2) counted twice and the 1 / M^2 folded in:
// Var(sum a_p N_p) = sum over the half spectrum of |r2c(a)|^2 power.
void metacal_noise_power(const MetacalFilters& filters, double input_variance, bool fixnoise, std::vector<double>* power);

// Var(sum a_p N_p) for maps a over a stamp of stamp_size^2 pixels, on the images' grid of period
// M. FFTW plan made at construction (allocates nothing after); one per thread.
class NoiseSpectrum {
 public:
  NoiseSpectrum(int stamp_size, int period);
  ~NoiseSpectrum();
  NoiseSpectrum(const NoiseSpectrum&) = delete;
  NoiseSpectrum& operator=(const NoiseSpectrum&) = delete;
  // a: stamp_size^2, row-major; power: metacal_noise_power's for this period.
  double variance(std::span<const double> a, std::span<const double> power);

 private:
  int s_, m_;
  AlignedBuffer padded_, spectrum_;
  void* plan_ = nullptr;
};

// One image's noise as the moments kernel takes it: a spectrum's machinery and a power (both must
// outlive its use).
class MetacalNoise final : public kernels::PixelCovariance {
 public:
  MetacalNoise() = default;
  MetacalNoise(NoiseSpectrum* spectrum, std::span<const double> power) : spectrum_(spectrum), power_(power) {}
  double variance(std::span<const double> a) override { return spectrum_->variance(a, power_); }

 private:
  NoiseSpectrum* spectrum_ = nullptr;
  std::span<const double> power_;
};

// The round Gaussian weights (FWHM, the fit's units) of a model fit's equivalent linear
// estimators (correct_fit_for_correlated_noise), for a fit of disc half-light radius `radius`.
// S/N: the fit's snr is its model's matched filter, and a Gaussian's matched filter is itself: the
// Gaussian of the object's FWHM, sqrt((2 r)^2 + FWHM_Gamma^2) (a Gaussian's FWHM is 2 r). Shape:
// adaptive moments are the maximum-likelihood shape of a Gaussian model (Bernstein & Jarvis
// 2002), but a fit's shape map r dm/dr follows the profile's wings, which an exponential disc
// (second moment 2.13 r^2, the FWHM-equivalent 2.43 r) and Gamma's Moffat wings carry further than
// a Gaussian of their FWHM: sqrt((2.43 r)^2 + (1.5 FWHM_Gamma)^2), chosen on grids against the
// scatter over noise (docs/metacal.md, "Errors and S/N": the FWHM-matched weight left the errors
// 14-30 % short, 2.5 Gamma ~10 % long at metacal_psf_dilation 1.5).
struct EquivalentWeights {
  double snr_fwhm = 0, shape_fwhm = 0;
};
EquivalentWeights equivalent_weights(double radius, double gamma_fwhm);

// A model fit's e errors and S/N, weighted as if the image's noise were white of its per-pixel
// variance, made those of the noise the images carry. A fit has no closed-form linear map from
// the pixels, so equivalent linear estimators stand in: the moments under the round Gaussian
// weights of equivalent_weights. Each e error is scaled by its estimator's correlated over white
// standard deviation, the S/N by the inverse of the flux's. stamps: the image with each cutout's
// variance and covariance (white when null). Where the moments are not valid the errors (or the
// S/N) become NaN and r gains kFlagNoErrors.
void correct_fit_for_correlated_noise(std::span<kernels::MomentsStamp> stamps, const EquivalentWeights& weights,
                                      std::vector<double>& scratch, FitResult* r);

}  // namespace stampede
