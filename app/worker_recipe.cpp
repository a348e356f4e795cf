// Workers' recipes; see worker_recipe.hpp.
#include "app/worker_recipe.hpp"

#include <memory>
#include <optional>

#include "app/fit_run.hpp"
#include "app/stamp_fitter_recipe.hpp"
#include "io/config_error.hpp"

namespace stampede::app {
namespace {

// The lines that are not option keys: a survey fit's tiles and bands.
constexpr const char* kTile = "mpi_meds";
constexpr const char* kBand = "mpi_band";

// A stamp run's measurers share the recipe (its PSF), which outlives them.
struct FitWorker {
  RunConfig config;
  std::vector<std::string> meds, bands;
  FftPlanCache setup_plans{FftPlanning::kEstimate};
  std::optional<StampFitterRecipe> recipe;
};

MeasurerFactory fit_measurers(const WorkerRecipe& recipe) {
  auto worker = std::make_shared<FitWorker>();
  for (const auto& [key, value] : recipe.lines) {
    if (key == kTile)
      worker->meds.push_back(value);
    else if (key == kBand)
      worker->bands.push_back(value);
    else
      set_option(worker->config, key, value);
  }
  validate(worker->config);
  if (!worker->meds.empty())
    return [worker]() -> std::unique_ptr<BatchFitter> {
      return make_survey_fitter(worker->config, worker->meds, worker->bands);
    };
  worker->recipe = stamp_fitter_recipe(worker->config, worker->setup_plans, worker->config.psf_from_catalogue);
  return [worker]() -> std::unique_ptr<BatchFitter> { return worker->recipe->make(FftPlanning::kEstimate); };
}

}  // namespace

WorkerRecipe fit_worker_recipe(const RunConfig& config, const std::vector<std::string>& meds,
                               const std::vector<std::string>& bands) {
  WorkerRecipe recipe{"fit", effective_options(config), config.batch_size};
  for (const std::string& m : meds) recipe.lines.emplace_back(kTile, m);
  for (const std::string& b : bands) recipe.lines.emplace_back(kBand, b);
  return recipe;
}

MeasurerFactory worker_measurers(const WorkerRecipe& recipe) {
  if (recipe.kind == "fit") return fit_measurers(recipe);
  throw io::ConfigError("worker recipe: no run is of the kind '" + recipe.kind + "'");
}

}  // namespace stampede::app
