// Metacalibration of one object seen in several cutouts (a MEDS tile's epochs): each cutout
// deconvolved by its own PSF, sheared on the sky (its WCS Jacobian carries the shear into its
// pixels, MetacalFilters), reconvolved with the object's one Gamma, round on the sky
// (sky_reconvolution states the rule), with a fixnoise field of its own weight map; then each of
// the five image sets fitted jointly (ObjectFitter), so e and R are in the sky's (u, v) axes.
// metacal_model = wmom fits nothing: each image set's weighted moments under a weight round on
// the sky, the cutouts combined (kernels/weighted_moments), its width in the cutouts' sky units.
//
// Cutouts with masked pixels are left out (nothing can be deconvolved there); when every cutout
// has some, all are used with those pixels zeroed and weightless, and the row is flagged, as the
// single-stamp path flags a masked stamp. One cutout whose frame is its pixel grid (unit
// Jacobian, flux scale 1) gives the single-stamp MetacalFitter's fits bit for bit.
// One per thread; image sets per cutout size are made on first use and kept.
#pragma once

#include <cstdint>
#include <map>
#include <memory>
#include <span>
#include <string>
#include <vector>

#include "engine/fit/multi_band_result.hpp"
#include "engine/fit/object_fitter.hpp"
#include "engine/metacal/metacal_image_set.hpp"
#include "engine/metacal/metacal_noise.hpp"
#include "engine/metacal/metacal_options.hpp"
#include "engine/metacal/metacal_record.hpp"
#include "engine/metacal/reconvolution_psf.hpp"
#include "kernels/weighted_moments.hpp"

namespace stampede {

struct MetacalEpoch {
  std::span<const double> pixels;  // box_size^2, row-major
  std::span<const double> weight;  // inverse variance per pixel; 0 masks
  int box_size = 0;
  PixelFrame frame;
  const PsfModel* psf = nullptr;  // the cutout's PSF in its pixels
  double flux_scale = 1;          // data = flux_scale x model
  int band = 0;                   // multi-band objects: the cutout's band
};

class MultiEpochMetacalFitter {
 public:
  // fit_options: the run's (renderer exact); options.model picks the fits' model.
  MultiEpochMetacalFitter(const FitterOptions& fit_options, const MetacalOptions& options);
  ~MultiEpochMetacalFitter();

  // *noshear: the noshear fit (sky units); *record: R and the sheared fits; *flags gains
  // failure_flag when R is unusable (a fit not ok, masked pixels in every cutout, no Gamma);
  // *problem (when empty) the first reason. object_id keys the fixnoise fields. Epochs of
  // `n_bands` bands (their `band` in 0..n_bands-1): *bands (when not null) gets the noshear fit's
  // per-band part.
  void fit(std::span<const MetacalEpoch> epochs, std::int64_t object_id, std::uint32_t failure_flag, FitResult* noshear,
           MetacalRecord* record, std::uint32_t* flags, std::string* problem, int n_bands = 1,
           std::vector<BandFit>* bands = nullptr);

  // The last object's: Gamma's FWHM on the sky (NaN when none served), cutouts used.
  double gamma_fwhm() const { return gamma_fwhm_; }
  int epochs_used() const { return epochs_used_; }
  // metacal_model = wmom: the weight's FWHM on the sky for the last object (NaN when no Gamma).
  double weight_fwhm() const;
  // The five images of cutout k of the last object's used ones (kMetacalTypes order).
  std::span<const double> images(std::size_t k) const { return images_[k]; }

 private:
  MetacalImageSet& set_for(int box_size);
  // metacal_model = wmom: image set t's moments over the used cutouts (per_band: and each band's
  // weighted flux and S/N).
  MultiBandFitResult measure_moments(MetacalType t, int n_bands, bool per_band);
  // stamps_: image set t of the used cutouts of `band` (< 0: all) with their noise; *unweighted
  // (when not null) gains whether one is noise-free (measured in data units).
  void moment_stamps(MetacalType t, int band, bool* unweighted);
  FitterOptions fit_options_;
  MetacalOptions options_;
  ObjectFitter fitter_;
  std::map<int, std::unique_ptr<MetacalImageSet>> sets_;
  std::vector<std::vector<double>> images_, weights_;
  std::vector<const MetacalEpoch*> used_;
  std::vector<MetacalEpochPsf> psfs_;
  std::vector<std::shared_ptr<const PreparedPsf>> prepared_;
  std::vector<Observation> fit_epochs_;
  std::vector<double> variances_;  // each used cutout's image noise variance (0: noise-free)
  // Each used cutout's images' noise (metacal_noise.hpp): its power, and it as the moments take it.
  std::vector<std::vector<double>> noise_powers_;
  std::vector<MetacalNoise> noises_;
  std::vector<kernels::MomentsStamp> stamps_;
  std::vector<double> moments_scratch_;
  SkyReconvolution gamma_;
  double gamma_fwhm_ = NAN;
  int epochs_used_ = 0;
};

}  // namespace stampede
