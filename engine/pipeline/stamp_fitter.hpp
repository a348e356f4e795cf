// The pipeline's per-thread fitting state for grid and catalogue stamps: each stamp one observation
// in its pixel grid, fitted by the object fitter (or measured by metacal, the stamp one epoch in
// its pixel grid), and the run's PSF handling.
#pragma once

#include <memory>
#include <optional>

#include "engine/fit/object_fitter.hpp"
#include "engine/metacal/metacal_fitter.hpp"
#include "engine/pipeline/pipeline.hpp"
#include "engine/render/psf_cache.hpp"

namespace stampede {

// A metacal run: its options and the run's one PSF (ignored with per-object PSFs).
struct MetacalSetup {
  MetacalOptions options;
  PsfModel shared_psf;
};

class StampFitter final : public BatchFitter {
 public:
  // Either `shared_psf` (one PSF for every object; may be null if it could not be built) or
  // `per_object` (prepared PSFs of each object's batch PSF model) is used.
  // psf_e1/e2/fwhm describe the shared PSF in the output (NaN when unknown, e.g. an image PSF).
  StampFitter(const FitterOptions& options, std::shared_ptr<const PreparedPsf> shared_psf, PsfCache* per_object,
              FftPlanning planning, double psf_e1 = NAN, double psf_e2 = NAN, double psf_fwhm = NAN,
              std::optional<MetacalSetup> metacal = std::nullopt);
  void fit(StampBatch& batch) override;

 private:
  FitterOptions options_;
  FftPlanCache plans_;
  ObjectFitter fitter_;
  std::shared_ptr<const PreparedPsf> shared_psf_;
  PsfCache* per_object_;
  double psf_e1_, psf_e2_, psf_fwhm_;
  std::optional<MetacalSetup> metacal_;
  std::unique_ptr<MetacalFitter> metacal_fitter_;  // metacal runs: replaces fitter_'s fit
  std::string metacal_problem_;  // why metacal could not calibrate the stamp (not in the row)
};

}  // namespace stampede
