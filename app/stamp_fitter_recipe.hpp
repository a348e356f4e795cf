// What every fitter of a run over stamps (grids, catalogues, arrays) is built from, made in one
// place: the command line, the Python module and the MPI driver's workers build their fitters
// from the same recipe, so one set of options gives one fitter wherever it runs (a worker that
// assembled its own once fitted plain rows in a metacal run).
#pragma once

#include <cmath>
#include <memory>
#include <optional>
#include <string>

#include "engine/pipeline/stamp_fitter.hpp"
#include "engine/render/fft_plans.hpp"
#include "engine/render/psf_cache.hpp"
#include "app/run_config.hpp"

namespace stampede::app {

struct StampFitterRecipe {
  FitterOptions options;                          // renderer = auto resolved when the PSF is shared
  std::shared_ptr<const PreparedPsf> shared_psf;  // null with per-object PSFs
  PsfModel psf_model;                             // the shared PSF's model
  std::unique_ptr<PsfCache> psf_cache;            // per-object PSFs only
  std::string auto_note;                          // why renderer = auto chose upsampled, if it did
  double psf_e1 = NAN, psf_e2 = NAN, psf_fwhm = NAN;  // the shared PSF as written to the rows
  std::optional<MetacalSetup> metacal;
  double gamma_fwhm = NAN;  // metacal with a shared PSF: the reconvolution PSF's FWHM

  // One pipeline thread's fitter (thread-compatible: the recipe outlives every fitter it makes).
  std::unique_ptr<StampFitter> make(FftPlanning planning) const;
};

// config's recipe: per_object, a PSF per object (prepared through a cache); else `psf` when given
// (`what` names it in errors) or the PSF config describes (build_shared_psf). A metacal run's
// reconvolution PSF is checked here (checked_reconvolution_psf), before any fitting.
StampFitterRecipe stamp_fitter_recipe(const app::RunConfig& config, FftPlanCache& plans, bool per_object,
                                      const std::optional<PsfModel>& psf = std::nullopt,
                                      const std::string& what = "");

}  // namespace stampede::app
