// Workers' recipes; see worker_recipe.hpp.
#include "app/worker_recipe.hpp"

#include <memory>
#include <optional>

#include "app/fit_run.hpp"
#include "app/metadetect_option_keys.hpp"
#include "app/stamp_fitter_recipe.hpp"
#include "engine/metadetect/cell_batch_measurer.hpp"
#include "engine/metadetect/sep_detection.hpp"
#include "io/config_error.hpp"

namespace stampede::app {
namespace {

// The lines that are not option keys (a fit's tiles and bands, a metadetection's band roles and
// pixel stack).
constexpr const char* kTile = "mpi_meds";
constexpr const char* kBand = "mpi_band";
constexpr const char* kDetectBands = "mpi_detect_bands";
constexpr const char* kShearBands = "mpi_shear_bands";
constexpr const char* kPixelStack = "mpi_pixel_stack";

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

MetadetectOptions metadetect_recipe_options(const WorkerRecipe& recipe, long long* pixel_stack) {
  MetadetectOptions options;
  for (const auto& [key, value] : recipe.lines) {
    if (key == kDetectBands) {
      options.detect_bands = static_cast<std::uint32_t>(std::stoul(value));
    } else if (key == kShearBands) {
      options.shear_bands = static_cast<std::uint32_t>(std::stoul(value));
    } else if (key == kPixelStack) {
      *pixel_stack = std::stoll(value);
    } else {
      const MetadetectOptionKey* option = nullptr;
      for (const MetadetectOptionKey& k : metadetect_option_keys())
        if (k.header == key) option = &k;
      if (!option) throw io::ConfigError("worker recipe: no metadetect option is recorded as '" + key + "'");
      if (const std::string why = option->set(options, value); !why.empty())
        throw io::ConfigError("worker recipe: " + key + " = '" + value + "': " + why);
    }
  }
  std::string why;
  if (!options.IsValid(&why)) throw io::ConfigError("worker recipe: " + why);
  return options;
}

WorkerRecipe fit_worker_recipe(const RunConfig& config, const std::vector<std::string>& meds,
                               const std::vector<std::string>& bands) {
  WorkerRecipe recipe{"fit", effective_options(config), config.batch_size};
  for (const std::string& m : meds) recipe.lines.emplace_back(kTile, m);
  for (const std::string& b : bands) recipe.lines.emplace_back(kBand, b);
  return recipe;
}

WorkerRecipe metadetect_worker_recipe(const MetadetectOptions& options, long long pixel_stack, int cells_per_batch) {
  WorkerRecipe recipe{"metadetect", metadetect_header_keys(options), cells_per_batch};
  recipe.lines.emplace_back(kDetectBands, std::to_string(options.detect_bands));
  recipe.lines.emplace_back(kShearBands, std::to_string(options.shear_bands));
  recipe.lines.emplace_back(kPixelStack, std::to_string(pixel_stack));
  return recipe;
}

MeasurerFactory worker_measurers(const WorkerRecipe& recipe) {
  if (recipe.kind == "fit") return fit_measurers(recipe);
  if (recipe.kind == "metadetect") {
    long long pixel_stack = 0;
    const MetadetectOptions options = metadetect_recipe_options(recipe, &pixel_stack);
    set_detection_pixel_stack(pixel_stack);
    return [options]() -> std::unique_ptr<BatchFitter> { return std::make_unique<CellBatchMeasurer>(options); };
  }
  throw io::ConfigError("worker recipe: no run is of the kind '" + recipe.kind + "'");
}

}  // namespace stampede::app
