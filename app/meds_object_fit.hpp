// One MEDS object fitted on all its usable single-epoch cutouts (issue 20): each cutout read from
// the tile, masked (zero weight, bmask bits, uberseg from the seg map), given its PSF (the PSFEx
// model of its source image at the object's position there) and its frame (the WCS Jacobian), its
// flux scaled to the reference zero point, and the object fitted jointly (MultiEpochFitter).
// The seam for `stampede fit --meds`, which is not yet built: this fits one object at a time.
#pragma once

#include <cstdint>
#include <filesystem>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "engine/fit/multi_band_result.hpp"
#include "engine/fit/multi_epoch_fitter.hpp"
#include "engine/metacal/multi_epoch_metacal_fitter.hpp"
#include "engine/model/psfex_model.hpp"
#include "engine/pipeline/object_record.hpp"
#include "io/meds_file.hpp"
#include "io/meds_options.hpp"

namespace stampede::app {

using MedsModel = io::MedsModel;

struct MedsFitOptions : io::MedsOptions {
  FitterOptions fitter;  // renderer must be exact; stamp_size is each cutout's; amplitudes free for bd
  PsfModel psf_model;    // psf = kOptions: the PSF of every cutout, in its pixels
  MetacalOptions metacal;  // enabled: each object's five metacal fits (MultiEpochMetacalFitter)
};

struct MedsObjectResult {
  std::int64_t id = -1, number = -1;
  double ra = NAN, dec = NAN;
  FitResult fit;  // sky units: e in (u, v), radius in arcsec, fluxes at magzp_ref
  std::uint32_t flags = 0;
  int n_epochs = 0;                 // cutouts fitted
  double masked_fraction = NAN;     // of the usable cutouts' pixels
  double psf_e1 = NAN, psf_e2 = NAN, psf_size = NAN;  // mean over the fitted cutouts, pixel frame, adaptive moments
  std::string problem;              // why cutouts or the object were not used (the first reason)
  bool bulge_or_disc = false;       // the model was bord
  bool is_bulge = false;            // bord: the pure bulge won
  double other_likelihood = NAN;    // bord: the losing model's
  MetacalRecord metacal;            // metacal runs: R and the sheared fits (fit is the noshear one)
  double gamma_fwhm = NAN;          // metacal runs: the reconvolution PSF's FWHM on the sky, arcsec
  long long pixels_total = 0, pixels_unmasked = 0;  // of the usable cutouts (masked_fraction's terms)
  std::vector<BandFit> bands;       // multi-band runs: per band (MultiBandObjectFitter)
};

class MedsObjectFitter {
 public:
  // `meds` must outlive it. Throws std::invalid_argument for options that cannot work (renderer, meds_psf =
  // cutouts on a tile without them), naming the option.
  MedsObjectFitter(io::MedsFile& meds, const MedsFitOptions& options);
  ~MedsObjectFitter();
  MedsObjectResult fit(long long row);
  // Reads object `row`'s usable cutouts into epochs(), each one's PSF prepared for its box by a
  // renderer of the options (any fitter of them may fit them); *out gets the object's identity,
  // flags, problem, n_epochs, masked fraction and PSF means. False when nothing is to be fitted
  // (out's flags say why).
  bool collect(long long row, MedsObjectResult* out);
  const std::vector<EpochData>& epochs() const { return epochs_; }
  // Metacal runs: the PSF of each of epochs(), unprepared.
  const std::vector<PsfModel>& epoch_psfs() const { return epoch_psfs_; }
  const io::MedsFile& meds() const { return meds_; }
  // What the last fit used for cutout k of its epochs (for tests: the PSF from its PSFEx model or
  // the tile's psf cutout; null for the options' analytic PSF).
  const std::vector<std::shared_ptr<const PsfImage>>& last_psfs() const { return last_psfs_; }
  // The PSFEx files the fits would read (image_info's psf_path resolved against meds_psf_dir), in
  // image_info order, without repeats; empty unless the PSFs come from PSFEx models.
  std::vector<std::string> psfex_files() const;

 private:
  std::filesystem::path psfex_file(const std::string& psf_path) const;
  // The PSFEx model of image_info row `file_id`, loaded on first use; null with *problem if not.
  const PsfexModel* psfex(long long file_id, std::string* problem);
  // Cutout k's PSF from the configured source, prepared for its box; null with *why if none.
  // *used: the PSF image it came from (null for the options' analytic PSF).
  std::shared_ptr<const PreparedPsf> cutout_psf(const io::MedsObject& o, int k, std::shared_ptr<const PsfImage>* used,
                                                std::string* why);

  io::MedsFile& meds_;
  MedsFitOptions options_;
  MultiEpochFitter fitter_;  // bd; bord: the pure disc
  std::unique_ptr<MultiEpochFitter> bulge_fitter_;  // bord: the pure bulge
  std::unique_ptr<MultiEpochMetacalFitter> metacal_;  // metacal runs
  std::vector<std::optional<PsfexModel>> models_;
  std::vector<std::string> model_errors_;
  // Per cutout of the current object: pixels, weights, and scratch for seg and bmask.
  std::vector<std::vector<double>> pixels_, weights_;
  std::vector<double> seg_, bmask_;
  io::MedsPsfSource source_;  // resolved: never kAuto
  std::map<int, std::shared_ptr<const PreparedPsf>> options_psf_;  // source kOptions, per box size
  std::vector<std::shared_ptr<const PsfImage>> last_psfs_;
  std::vector<EpochData> epochs_;  // the current object's, reused
  std::vector<PsfModel> epoch_psfs_;              // metacal: the current object's PSFs, unprepared
  std::vector<MetacalEpoch> metacal_epochs_;
};

// The options with one amplitude fixed at 0 (bord's pure bulge or pure disc).
FitterOptions single_component(FitterOptions o, Param zero);

// Uberseg: in a box_size^2 seg cutout, zero the weight of every pixel whose nearest labelled seg
// pixel (Euclidean, pixel centres) belongs to another object than `number`; ties keep the pixel.
// A cutout with no labelled pixel is left alone.
void apply_uberseg(std::span<const double> seg, int box_size, std::int64_t number, std::span<double> weight);

}  // namespace stampede::app
