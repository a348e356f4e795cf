// One object's metacalibration: the five images (MetacalImager), the fixnoise field through the
// same operations, and the five fits with the reconvolution PSF; e from noshear, R from the
// sheared four. One per thread; buffers allocated at construction, filters rebuilt only when the
// PSF changes.
#pragma once

#include <cstdint>
#include <memory>
#include <span>
#include <string>
#include <vector>

#include "engine/fit/object_fitter.hpp"
#include "engine/metacal/metacal_image_set.hpp"
#include "engine/metacal/metacal_options.hpp"
#include "engine/metacal/metacal_record.hpp"
#include "kernels/weighted_moments.hpp"

namespace stampede {

// The fit options of metacal's model: bd keeps them; exp and gauss fit one component, the other's
// amplitude held at 0 (gauss: a Sersic n = 0.5 bulge).
FitterOptions metacal_fit_options(FitterOptions o, MetacalModel model);

// metacal_model = wmom: weighted moments as a row (e, centroid, radius, S/N, errors; flux the
// weighted flux; the radius the half-light radius of the Gaussian with that weighted T).
// unweighted: measured on noise-free images in data units (flagged kFlagUnweighted).
FitResult weighted_moments_row(const kernels::WeightedMoments& m, bool unweighted, int n_pixels);

class MetacalFitter {
 public:
  // fit_options must be valid (the fits' renderer, model, solver; noise_sigma is the data's);
  // options.enabled is not consulted. planning: the image operations' and the fits' FFT plans.
  MetacalFitter(const FitterOptions& fit_options, const MetacalOptions& options, int stamp_size, FftPlanning planning);

  // Prepares the filters and the reconvolution PSF for `psf` (nothing when it is the last one).
  // False, with *error, when metacal cannot use this PSF: the following fits report kPsfFailure.
  bool set_psf(const PsfModel& psf, std::string* error);

  // Fits the five images of one stamp. *noshear: the noshear fit (the row's e); *record: R and the
  // sheared fits; *flags gains kFlagMetacalFailure (object_record.hpp's bit, passed in) when a
  // sheared fit is unusable or pixels are masked. object_id keys the fixnoise field.
  void fit(std::span<const double> pixels, std::span<const double> weight, WeightKind kind, std::int64_t object_id,
           std::uint32_t failure_flag, FitResult* noshear, MetacalRecord* record, std::uint32_t* flags);

  // The five images of one stamp into images(), fixnoise included (set_psf must have succeeded);
  // *image_variance: their per-pixel noise variance (0 for noise-free data). False when pixels
  // are masked (zeroed, as nothing can be deconvolved there).
  bool make_images(std::span<const double> pixels, std::span<const double> weight, WeightKind kind,
                   std::int64_t object_id, double* image_variance);

  // The five images of the last fit (kMetacalTypes order, stamp_size^2 each), fixnoise included.
  std::span<const double> images() const { return images_; }
  const PsfModel& reconvolution() const { return gamma_; }
  // metacal_model = wmom: the weight's FWHM in pixels for the current PSF (NaN before set_psf).
  double weight_fwhm() const;
  double noise_gain() const { return filters_ ? filters_->noise_gain() : NAN; }

 private:
  FitterOptions fit_options_;
  MetacalOptions options_;
  int s_;
  MetacalImageSet images_set_;
  ObjectFitter fitter_;  // fits each image as one observation in its pixel grid, with gamma_
  Observation image_;    // the image being fitted: gamma_'s prepared PSF, the images' weights
  std::shared_ptr<const MetacalFilters> filters_;
  PsfModel psf_, gamma_;
  bool have_psf_ = false;
  // metacal_model = wmom: one image's weighted moments as a row (e, centroid, radius, S/N, errors;
  // flux the weighted flux), errors and S/N for the noise of noise_power_.
  FitResult moments_result(std::span<const double> image, double variance);
  std::vector<double> images_, weight_, scratch_;
  std::vector<double> noise_power_;  // the images' noise power (metacal_noise.hpp); empty when noise-free
};

}  // namespace stampede
