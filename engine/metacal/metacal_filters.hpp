// The Fourier-space filters of metacalibration's image operations, one per image type, on an
// M x M periodic grid: f_T(q) = Gamma~(A_T^-T q) pix~(A_T^-T q) / (P~(q) pix~(q)), with P the
// observed PSF, Gamma the reconvolution PSF, pix~ the pixel's top-hat and A_T the type's shear in
// the stamp's pixels. The shear is applied on the sky: through a cutout's WCS Jacobian J (frame)
// the sky's A becomes J^-1 A J in its pixels, no longer symmetric; the identity frame keeps A.
//
// Applied to the data's transform and shifted back to real space it gives H_T, the deconvolved
// galaxy convolved with the *unsheared-back* reconvolution kernel; the image of type T is then
// H_T(c + A_T^-1 (x - c)) (MetacalImager). Built once per distinct PSF, immutable, shared.
#pragma once

#include <array>
#include <complex>
#include <memory>
#include <string>
#include <vector>

#include "engine/metacal/metacal_type.hpp"
#include "engine/model/pixel_frame.hpp"
#include "engine/model/psf_model.hpp"

namespace stampede {

class MetacalFilters {
 public:
  // The observed PSF x pixel on the grid, which the filters for any Gamma divide by: computed once
  // per PSF when several Gammas are tried.
  struct Observed {
    ~Observed();  // hands its arrays to this thread's pool for the next
    int period = 0;
    std::vector<std::complex<double>> values;  // (period + 1) rows x (period / 2 + 1)
    // 1 / values and 1 / |values|: the filters multiply by them (a search builds ~10 per PSF).
    std::vector<std::complex<double>> inverse;
    std::vector<double> inverse_abs;
  };
  // Null, with *error, when the PSF's transform is not finite and non-zero on the grid.
  static std::shared_ptr<const Observed> observe(const PsfModel& psf, int period, std::string* error);

  // period: M (even). Null, with *error, when a filter is not finite (a PSF whose transform
  // vanishes or is NaN on the grid, e.g. an obscured Airy disc) or exceeds `max_gain` anywhere:
  // a reconvolution PSF wider than the (sheared) PSF in every direction keeps it below 1 (its
  // value at k = 0), and one that is not amplifies the noise at high k.
  // psf and reconvolution are in the stamp's pixels; frame: the stamp's pixels to the sky in which
  // the shear is applied (the identity: the pixels themselves).
  static std::shared_ptr<const MetacalFilters> build(const PsfModel& psf, const PsfModel& reconvolution, double step,
                                                     int period, std::string* error, double max_gain = 1.01,
                                                     const PixelFrame& frame = PixelFrame());
  // The same from the observed PSF; reconvolution must be a Moffat or a Gaussian.
  static std::shared_ptr<const MetacalFilters> build(const Observed& observed, const PsfModel& reconvolution, double step,
                                                     std::string* error, double max_gain = 1.01,
                                                     const PixelFrame& frame = PixelFrame());

  // Whether build's first, coarse check (every third row and column, and the axes) passes: a Gamma
  // that fails it is refused by build, and a wider round Gamma (a smaller transform at every k)
  // passes whenever a narrower one does, so a search for the narrowest Gamma can bisect on it at
  // a seventh of a build.
  static bool passes_coarse_check(const Observed& observed, const PsfModel& reconvolution, double step,
                                  double max_gain = 1.01, const PixelFrame& frame = PixelFrame());

  ~MetacalFilters();  // hands its arrays to this thread's pool for the next filters

  int period() const { return period_; }
  double step() const { return step_; }
  // Half-spectrum (period rows x period/2 + 1 columns) of type t, FFTW's 1/M^2 included, the
  // Nyquist row and column split symmetrically so that the product stays Hermitian.
  const std::complex<double>* filter(MetacalType t) const { return filters_[static_cast<int>(t)].data(); }
  // The same rounded to float, for single-precision images (half the memory traffic of a product).
  const std::complex<float>* single_filter(MetacalType t) const { return single_filters_[static_cast<int>(t)].data(); }
  // The variance that white noise of unit variance has after the noshear filter: mean |f|^2.
  double noise_gain() const { return noise_gain_; }
  // A_T^-1 in the stamp's pixels, row-major: the image of type T is H_T(c + A_T^-1 (x - c)).
  const std::array<double, 4>& inverse_shear(MetacalType t) const { return inverse_[static_cast<int>(t)]; }
  const PsfModel& reconvolution() const { return reconvolution_; }

 private:
  MetacalFilters() = default;
  int period_ = 0;
  double step_ = 0;
  double noise_gain_ = 0;
  PsfModel reconvolution_;
  std::array<std::vector<std::complex<double>>, kNumMetacalTypes> filters_;
  std::array<std::vector<std::complex<float>>, kNumMetacalTypes> single_filters_;
  std::array<std::array<double, 4>, kNumMetacalTypes> inverse_{};
};

}  // namespace stampede
