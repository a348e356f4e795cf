// One recipe for every stamp run's fitters; see stamp_fitter_recipe.hpp.
#include "app/stamp_fitter_recipe.hpp"

#include "app/psf_setup.hpp"
#include "engine/common/number_text.hpp"
#include "io/config_error.hpp"

namespace stampede::app {

std::unique_ptr<StampFitter> StampFitterRecipe::make(FftPlanning planning) const {
  return std::make_unique<StampFitter>(options, shared_psf, psf_cache.get(), planning, psf_e1, psf_e2, psf_fwhm,
                                       metacal);
}

StampFitterRecipe stamp_fitter_recipe(const app::RunConfig& config, FftPlanCache& plans, bool per_object,
                                      const std::optional<PsfModel>& psf, const std::string& what) {
  StampFitterRecipe r;
  r.options = config.fitter;
  if (config.metacal.enabled) r.metacal = MetacalSetup{config.metacal, {}};
  if (per_object) {  // renderer = auto stays auto: each object's PSF chooses when it is prepared
    r.psf_cache = std::make_unique<PsfCache>(1024);
    return r;
  }
  const SharedPsf shared = psf ? prepare_shared_psf(*psf, config, plans, what) : build_shared_psf(config, plans);
  r.options.renderer = shared.kind;
  r.shared_psf = shared.prepared;
  r.psf_model = shared.model;
  r.auto_note = shared.auto_note;
  r.psf_e1 = shared.e1, r.psf_e2 = shared.e2, r.psf_fwhm = shared.fwhm;
  if (r.metacal) {
    r.gamma_fwhm = checked_reconvolution_psf(shared.model, config).fwhm();
    // A moments weight narrower than Γ, the images' PSF, measures no response (docs/metacal.md
    // measures 1.5 Γ and wider); a MEDS run, whose Γ is per object, flags such rows instead.
    if (config.metacal.model == MetacalModel::kWeightedMoments && config.metacal.weight_fwhm > 0 &&
        config.metacal.weight_fwhm < r.gamma_fwhm)
      throw io::ConfigError("metacal_weight_fwhm = " + app::get_option(config, "metacal_weight_fwhm") +
                            " is narrower than the reconvolution PSF Γ (FWHM " + number_text(r.gamma_fwhm) +
                            " px): the moments' weight must be at least as wide (default 2.5 Γ: 0)");
    r.metacal->shared_psf = shared.model;
  }
  return r;
}

}  // namespace stampede::app
