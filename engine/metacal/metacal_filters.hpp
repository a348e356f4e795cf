// The Fourier-space filters of metacalibration's image operations, one per image type, on an
// M x M periodic grid: f_T(q) = Gamma~(A_T^-1 q) pix~(A_T^-1 q) / (P~(q) pix~(q)), with P the
// observed PSF, Gamma the reconvolution PSF, pix~ the pixel's top-hat and A_T the type's shear.
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
#include "engine/model/psf_model.hpp"

namespace stampede {

class MetacalFilters {
 public:
  // period: M (even). Null, with *error, when a filter is not finite (a PSF whose transform
  // vanishes or is NaN on the grid, e.g. an obscured Airy disc) or exceeds `max_gain` anywhere:
  // a reconvolution PSF wider than the (sheared) PSF in every direction keeps it below 1 (its
  // value at k = 0), and one that is not amplifies the noise at high k.
  static std::shared_ptr<const MetacalFilters> build(const PsfModel& psf, const PsfModel& reconvolution, double step,
                                                     int period, std::string* error, double max_gain = 1.01);

  int period() const { return period_; }
  double step() const { return step_; }
  // Half-spectrum (period rows x period/2 + 1 columns) of type t, FFTW's 1/M^2 included, the
  // Nyquist row and column split symmetrically so that the product stays Hermitian.
  const std::complex<double>* filter(MetacalType t) const { return filters_[static_cast<int>(t)].data(); }
  // The variance that white noise of unit variance has after the noshear filter: mean |f|^2.
  double noise_gain() const { return noise_gain_; }
  const PsfModel& reconvolution() const { return reconvolution_; }

 private:
  MetacalFilters() = default;
  int period_ = 0;
  double step_ = 0;
  double noise_gain_ = 0;
  PsfModel reconvolution_;
  std::array<std::vector<std::complex<double>>, kNumMetacalTypes> filters_;
};

}  // namespace stampede
