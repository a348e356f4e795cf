// One survey object fitted on its observations: the cutouts a MEDS source read into the batch's
// arena (io/meds_object_source), of one band or several. Each cutout's PSF is prepared here, in
// the parallel fit stage, by this thread's renderers; the object is then fitted jointly on every
// usable cutout (ObjectFitter: one shape, a bulge and a disc amplitude per band), bord choosing the
// pure bulge or the pure disc, or measured by
// metacalibration (MetacalFitter: one Gamma over every cutout, R the combined response).
// A band whose cutouts are all unusable is left out of a multi-band fit (its n_epochs 0, its
// problem in the row's, prefixed with the band). One band named by --bands is the single tile's fit
// with band columns, so its rows are a single-tile run's.
//
// SurveyBatchFitter is the pipeline's per-thread fitting state for such batches; a row depends on
// its object alone, so any thread or rank count gives the same table.
#pragma once

#include <cstdint>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include "engine/fit/multi_band_result.hpp"
#include "engine/fit/object_fitter.hpp"
#include "engine/metacal/metacal_fitter.hpp"
#include "engine/pipeline/object_record.hpp"
#include "engine/pipeline/pipeline.hpp"
#include "io/meds_options.hpp"

namespace stampede::app {

using MedsModel = io::MedsModel;

struct MedsFitOptions : io::MedsOptions {
  FitterOptions fitter;  // renderer must be exact; stamp_size is each cutout's; amplitudes free for bd
  PsfModel psf_model;    // psf = kOptions: the PSF of every cutout, in its pixels
  MetacalOptions metacal;  // enabled: each object's five metacal fits (MetacalFitter)
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
  std::vector<BandFit> bands;       // band columns: per band
};

class SurveyObjectFitter {
 public:
  // tiles: each band's tile path (for messages); bands: their names, in the same order, or empty for
  // one tile without band columns. Throws std::invalid_argument for options that cannot work (bord
  // with metacal), naming the option.
  SurveyObjectFitter(const MedsFitOptions& options, std::vector<std::string> tiles, std::vector<std::string> bands);
  ~SurveyObjectFitter();
  // Object `object` of the arena (object_data row `row`, identity in `identity`).
  MedsObjectResult fit(const ObservationArena& arena, int object, long long row, const ObjectRecord& identity);

 private:
  // Band b's usable cutouts appended to epochs_ (their PSFs prepared) and *out's reading figures;
  // false when the band cannot be fitted (out's flags say why).
  bool collect(const ObservationArena& arena, int object, int band, long long row, MedsObjectResult* out);
  std::shared_ptr<const PreparedPsf> prepare(const ArenaObservation& o, std::string* why);
  void fit_one_band(const ObservationArena& arena, int object, long long row, MedsObjectResult* out);
  void fit_bands(const ObservationArena& arena, int object, long long row, MedsObjectResult* out);

  MedsFitOptions options_;
  std::vector<std::string> tiles_;
  std::vector<std::string> bands_;
  ObjectFitter fitter_;  // bd; bord: the pure disc. Its renderers prepare every cutout's PSF
  std::unique_ptr<ObjectFitter> bulge_fitter_;  // bord: the pure bulge
  std::unique_ptr<MetacalFitter> metacal_;    // metacal runs
  std::map<int, std::shared_ptr<const PreparedPsf>> options_psf_;  // meds_psf = options, per box size
  std::vector<Observation> epochs_;  // the current object's, PSFs prepared and as models (metacal), reused
  std::vector<BandFit> bulge_bands_;  // bord over bands: the pure bulge's band parts, reused
};

class SurveyBatchFitter final : public BatchFitter {
 public:
  // Each object's row into batch.records, its first problem into batch.problems.
  SurveyBatchFitter(const MedsFitOptions& options, std::vector<std::string> tiles, std::vector<std::string> bands);
  void fit(StampBatch& batch) override;

 private:
  SurveyObjectFitter fitter_;
};

// The options with one amplitude fixed at 0 (bord's pure bulge or pure disc).
FitterOptions single_component(FitterOptions o, Param zero);

// The output row of one object's result (survey columns; e, radius and fluxes in sky units; band
// columns in record.survey.bands).
void fill_survey_record(const MedsObjectResult& result, ObjectRecord* record);

}  // namespace stampede::app
