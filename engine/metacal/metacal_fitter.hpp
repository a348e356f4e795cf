// One object's metacalibration, on one stamp or on its cutouts (a MEDS tile's epochs, of one band
// or several): each epoch deconvolved by its own PSF, sheared on the sky (its WCS Jacobian carries
// the shear into its pixels, MetacalFilters), reconvolved with the object's one Gamma, round on the
// sky (sky_reconvolution states the rule), with a fixnoise field of its own noise
// (MetacalImageSet); then each of the five image sets fitted jointly (ObjectFitter) with Gamma, so
// e and R are in the sky's (u, v) axes: e from noshear, R from the sheared four.
// metacal_model = wmom fits nothing: each image set's weighted moments under a weight round on the
// sky, the epochs combined (kernels/weighted_moments), its width in the epochs' sky units.
//
// A grid or catalogue stamp is one epoch whose frame is its pixel grid (unit Jacobian, flux scale
// 1): its Gamma is the single-PSF rule's (reconvolution_filters) and its fits are single-stamp fits.
// Epochs with masked pixels are left out (nothing can be deconvolved there); when every epoch has
// some, all are used with those pixels zeroed, and the row is flagged.
// One per thread. Image sets per box size are made on first use and kept; Gamma, its filters and
// its prepared PSFs are kept while the epochs' PSFs, frames and box sizes are the last object's
// (a run's one PSF: computed once), so a run of stamps allocates nothing per object.
#pragma once

#include <cstdint>
#include <map>
#include <memory>
#include <span>
#include <string>
#include <vector>

#include "engine/fit/multi_band_result.hpp"
#include "engine/fit/object_fitter.hpp"
#include "engine/fit/observation.hpp"
#include "engine/metacal/metacal_image_set.hpp"
#include "engine/metacal/metacal_noise.hpp"
#include "engine/metacal/metacal_options.hpp"
#include "engine/metacal/metacal_record.hpp"
#include "engine/metacal/reconvolution_psf.hpp"
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
  // How the images weigh in the fits. kDataMask (cutouts): 1 / their noise variance where the
  // data has weight, 0 where it is masked (1 for noise-free images). kUniform (grid and catalogue
  // stamps): 1 / their noise variance over the whole box, masked (zeroed) pixels included, and
  // noise_sigma's (unweighted) for noise-free images; a masked stamp's row is flagged unusable.
  enum class ImageWeight { kDataMask, kUniform };

  // fit_options must be valid (renderer exact for frames other than the pixel grid; noise_sigma is
  // the data's where an epoch has no weight map); options.model picks the fits' model, and
  // options.enabled is not consulted. planning: the image operations' and the fits' FFT plans.
  MetacalFitter(const FitterOptions& fit_options, const MetacalOptions& options,
                FftPlanning planning = FftPlanning::kEstimate, ImageWeight image_weight = ImageWeight::kDataMask);
  ~MetacalFitter();

  // epochs: each with its psf_model (their prepared psf is not read: the fits draw with Gamma).
  // *noshear: the noshear fit (sky units); *record: R and the sheared fits; *flags gains
  // failure_flag when R is unusable (a fit not ok, masked pixels in every epoch, no Gamma, bad
  // pixels); *problem (when empty) the first reason. object_id keys the fixnoise fields. Epochs of
  // `n_bands` bands (their `band` in 0..n_bands-1): *bands (when not null) gets the noshear fit's
  // per-band part.
  void fit(std::span<const Observation> epochs, std::int64_t object_id, std::uint32_t failure_flag, FitResult* noshear,
           MetacalRecord* record, std::uint32_t* flags, std::string* problem, int n_bands = 1,
           std::vector<BandFit>* bands = nullptr);

  // The five images of one epoch into images(0), fixnoise included, nothing fitted (for tests and
  // benchmarks); *image_variance: their per-pixel noise variance (0 for noise-free data). False,
  // with *error, when no Gamma serves its PSF.
  bool make_images(const Observation& epoch, std::int64_t object_id, double* image_variance, std::string* error);

  // The last object's: Gamma's FWHM on the sky (NaN when none served), epochs used.
  double gamma_fwhm() const { return gamma_fwhm_; }
  int epochs_used() const { return epochs_used_; }
  // metacal_model = wmom: the weight's FWHM on the sky for the last object (NaN when no Gamma).
  double weight_fwhm() const;
  // The five images of the last object's used epoch k (kMetacalTypes order, box_size^2 each), and
  // Gamma in its pixels.
  std::span<const double> images(std::size_t k) const { return images_[k]; }
  const PsfModel& reconvolution(std::size_t k) const { return gamma_.filters[k]->reconvolution(); }

 private:
  MetacalImageSet& set_for(int box_size);
  // Gamma of the used epochs into gamma_ (and, for model fits, prepared_): kept from the last call
  // while their PSFs, frames and box sizes are the same. False, with *error, when none serves.
  bool reconvolve(std::string* error);
  // The per-epoch buffers sized for used_ (grown, never shrunk: no allocation in steady state).
  void size_for_used();
  // Used epoch k's five images, fixnoise included, into images_[k], their noise into variances_,
  // noise_powers_ and noises_.
  void make_epoch_images(std::size_t k, std::int64_t object_id);
  // Used epoch k's weight in the fits of its images (image_weight_'s rule) into fit_weights_[k].
  void set_fit_weight(std::size_t k);
  // Image set t of the used epochs fitted jointly, with each band's part, or its moments (with
  // each band's part when per_band).
  const MultiBandFitResult& measure(MetacalType t, int n_bands, bool per_band);
  // metacal_model = wmom: image set t's moments over the used epochs (per_band: and each band's
  // weighted flux and S/N).
  void measure_moments(MetacalType t, int n_bands, bool per_band);
  // stamps_: image set t of the used epochs of `band` (< 0: all) with their noise; *unweighted
  // (when not null) gains whether one is noise-free (measured in data units).
  void moment_stamps(MetacalType t, int band, bool* unweighted);

  FitterOptions fit_options_;
  MetacalOptions options_;
  FftPlanning planning_;
  ImageWeight image_weight_;
  ObjectFitter fitter_;
  std::map<int, std::unique_ptr<MetacalImageSet>> sets_;
  std::vector<const Observation*> used_;
  std::vector<std::vector<double>> images_, weights_;
  std::vector<std::span<const double>> fit_weights_;  // each used epoch's (empty: noise_sigma's)
  std::vector<double> variances_;                      // each used epoch's image noise variance (0: noise-free)
  // Each used epoch's images' noise (metacal_noise.hpp): its power, and it as the moments take it.
  std::vector<std::vector<double>> noise_powers_;
  std::vector<MetacalNoise> noises_;
  // Gamma of the epochs it was made for (their PSFs, frames and box sizes), or why none served.
  std::vector<MetacalEpochPsf> psfs_;
  std::vector<PsfModel> gamma_psfs_;
  bool have_gamma_ = false, gamma_served_ = false;
  std::string gamma_error_;
  SkyReconvolution gamma_;
  std::vector<std::shared_ptr<const PreparedPsf>> prepared_;  // Gamma in each used epoch's pixels
  std::vector<Observation> fit_epochs_;
  MultiBandFitResult measured_;  // the last image set's fit or moments
  std::vector<kernels::MomentsStamp> stamps_;
  std::vector<double> moments_scratch_;
  double gamma_fwhm_ = NAN;
  int epochs_used_ = 0;
};

}  // namespace stampede
