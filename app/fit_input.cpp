// The fit run's inputs; see fit_input.hpp.
#include "app/fit_input.hpp"

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <optional>

#include <tbb/task_arena.h>

#include "app/psf_setup.hpp"
#include "app/run_memory.hpp"
#include "app/survey_object_fit.hpp"
#include "engine/common/number_text.hpp"
#include "engine/pipeline/stamp_fitter.hpp"
#include "io/catalogue_source.hpp"
#include "io/file_digest.hpp"
#include "io/fits_error.hpp"
#include "io/fits_file.hpp"
#include "io/grid_source.hpp"
#include "io/meds_object_source.hpp"
#include "io/option_text.hpp"
#include "io/psf_keys.hpp"
#include "io/simulation_identity.hpp"
#include "io/system_memory.hpp"

namespace stampede::app {

std::string images_path_for(std::string output) {
  if (output.size() > 5 && output.compare(output.size() - 5, 5, ".fits") == 0) output.resize(output.size() - 5);
  return output + ".images.fits";
}

namespace {

// The run's outputs and the files it writes beside them, as io::check_outputs takes them.
std::vector<io::RunOutput> outputs_of(const FitRunOptions& run, const app::RunConfig& config) {
  std::vector<io::RunOutput> out;
  out.push_back(table_output("-o", run.output));
  if (!run.text_output.empty())
    out.push_back({"--text", run.text_output, {run.text_output + ".partial", io::OutputLock::path_for(run.text_output)}});
  if (!config.save_images.empty()) out.push_back({"save_images", images_path_for(run.output), {}});
  return out;
}

// Every file the run reads, as it is on disk.
std::vector<io::RunInput> inputs_of(const FitRunOptions& run, const app::RunConfig& config,
                                   const std::vector<std::string>& psfex_files) {
  if (!run.meds.empty()) {
    std::vector<io::RunInput> in;
    for (const std::string& m : run.meds) in.push_back({"--meds", io::fits_root_name(m)});
    for (const std::string& p : psfex_files) in.push_back({"PSFEx model", p});
    return in;
  }
  std::vector<io::RunInput> in = {{"input", io::fits_root_name(run.input)}};
  if (!run.catalog.empty()) in.push_back({"--catalog", io::fits_root_name(run.catalog)});
  if (!run.weight.empty()) in.push_back({"--weight", io::fits_root_name(run.weight)});
  if (!config.psf_image.empty()) in.push_back({"psf_image", io::fits_root_name(config.psf_image)});
  if (!config.fft_wisdom.empty()) in.push_back({"fft_wisdom", config.fft_wisdom});
  return in;
}

// The run's outputs checked against every file it reads, and locked (app/run_harness).
std::vector<io::OutputLock> protect(const FitRunOptions& run, const TableRun& table, const app::RunConfig& config,
                                    const std::vector<std::string>& psfex_files = {}) {
  if (run.output.empty()) return {};
  return protect_outputs(table, outputs_of(run, config), inputs_of(run, config, psfex_files));
}

// What a grid's header says of itself, used as a user expects: the PSF it records (unless the run
// sets one), its noise (NOISESIG, unless the run sets noise_sigma or gives a weight map), the
// simulated set it is (*input_set), and its noise pairs (NOISEPR, for metacal's fixnoise fields).
void use_grid_records(const FitRunOptions& run, io::GridStampSource& grid, const TableRun& table, app::RunConfig* config,
                      std::optional<PsfModel>* recorded_psf, std::string* input_set) {
  const std::string where = grid.header().describe();
  try {
    *recorded_psf = io::read_psf_keys_if_present(grid.header());
  } catch (const io::FitsError& e) {  // the record is a convenience: the fit does not need it
    table.warn(std::string("the PSF record is unreadable, neither used nor checked: ") + e.what());
  }
  if (*recorded_psf && !app::sets_psf_options(*config)) app::use_recorded_psf(**recorded_psf, where, config);
  if (run.weight.empty() && !config->explicitly_set.count("noise_sigma")) {
    std::optional<double> sigma;
    try {
      sigma = grid.header().read_key_double("NOISESIG");
    } catch (const io::FitsError& e) {
      table.warn(std::string("the NOISESIG record is unreadable, not used: ") + e.what());
    }
    if (sigma && std::isfinite(*sigma) && *sigma > 0) {
      config->fitter.noise_sigma = *sigma;
      config->explicitly_set["noise_sigma"] = "";  // as if the run had set it
      table.warn("noise_sigma = " + number_text(*sigma) + " taken from " + where +
           " NOISESIG (the run sets none; set noise_sigma to override)");
    } else if (sigma && !(std::isfinite(*sigma) && *sigma >= 0)) {
      table.warn(where + " NOISESIG = " + number_text(*sigma) + " is not a noise level, not used");
    }
  }
  try {
    *input_set = io::simulation_identity(grid.header());
  } catch (const io::FitsError& e) {  // as the PSF record: only `metrics` checks it
    table.warn(std::string("the simulated set's identity is unreadable, not recorded: ") + e.what());
  }
  if (config->metacal.enabled && config->metacal.fixnoise) {  // a set simulated in noise pairs pairs its fixnoise fields
    std::optional<std::string> pairs;
    try {
      pairs = grid.header().read_key_string("NOISEPR");
    } catch (const io::FitsError& e) {
      table.warn(std::string("the NOISEPR record is unreadable, fixnoise fields not paired: ") + e.what());
    }
    config->metacal.noise_pairs = pairs && *pairs == "T";
  }
}

// The band names of a survey run: as given, b0, b1, ... for several tiles without names, none for
// one tile. Throws io::ConfigError for names the table cannot take.
std::vector<std::string> survey_bands(const FitRunOptions& run) {
  std::vector<std::string> bands = run.bands;
  if (bands.empty() && run.meds.size() > 1)
    for (std::size_t b = 0; b < run.meds.size(); ++b) bands.push_back("b" + std::to_string(b));
  if (!bands.empty() && bands.size() != run.meds.size())
    throw io::ConfigError("--bands names " + std::to_string(bands.size()) + " bands for " + std::to_string(run.meds.size()) +
                          " --meds tiles: one band per tile, in the order of the tiles");
  if (run.meds.size() > static_cast<std::size_t>(kMaxBands))
    throw io::ConfigError(std::to_string(run.meds.size()) + " --meds tiles: a multi-band fit takes at most " +
                          std::to_string(kMaxBands) + " bands");
  try {
    const io::ResultSchema names(io::PositionColumns::kSurvey, false, bands);  // the names as column suffixes
  } catch (const std::invalid_argument& e) {
    throw io::ConfigError(std::string("--bands: ") + e.what());
  }
  for (std::size_t t = 1; t < run.meds.size(); ++t)
    for (std::size_t u = 0; u < t; ++u)
      if (run.meds[t] == run.meds[u]) throw io::ConfigError("--meds '" + run.meds[t] + "' is given twice: one tile per band");
  return bands;
}

}  // namespace

FitInput open_stamp_input(const FitRunOptions& run, const TableRun& table) {
  FitInput in;
  app::RunConfig& config = in.config;
  config = run.config;
  if (!run.weight.empty() && config.fitter.noise_sigma != 0) {
    const auto where = config.explicitly_set.find("noise_sigma");
    const std::string from = where != config.explicitly_set.end() && !where->second.empty() ? " (" + where->second + ")" : "";
    throw io::ConfigError("option 'noise_sigma' = " + app::get_option(config, "noise_sigma") + from + " and --weight '" +
                          run.weight + "' both give the noise; give one (noise_sigma = 0 with a weight map)");
  }
  // A stamp size the run sets is checked before the input is read: an invalid one (0, negative)
  // must be refused, not replaced by the header's STAMPSZ.
  const bool stamp_from_header = run.catalog.empty() && !config.explicitly_set.count("stamp_size");
  if (!stamp_from_header) app::validate(config);
  const std::vector<std::int64_t> saved_ids = app::save_image_ids(config);
  in.locks = protect(run, table, config);  // before anything is read: a refused output costs nothing

  // Input first: its header may fix the stamp size, and a bad file should fail before anything.
  std::optional<PsfModel> recorded_psf;
  std::string recorded_where, input_set;
  if (run.catalog.empty()) {
    auto grid = std::make_unique<io::GridStampSource>(run.input, run.weight, stamp_from_header ? 0 : config.fitter.render.stamp_size);
    config.fitter.render.stamp_size = grid->stamp_size();
    recorded_where = grid->header().describe();
    use_grid_records(run, *grid, table, &config, &recorded_psf, &input_set);
    for (std::int64_t id : saved_ids)
      if (id < 0 || id >= grid->total_objects())
        throw io::ConfigError("option 'save_images': object id " + std::to_string(id) + " is not in '" + run.input +
                              "' (ids 0.." + std::to_string(grid->total_objects() - 1) + ")");
    in.whole = std::move(grid);
  } else {
    const io::CatalogueColumns cols{config.catalog_id_column,       config.catalog_x_column,       config.catalog_y_column,
                                    config.psf_from_catalogue,      config.catalog_psf_beta_column, config.catalog_psf_fwhm_column,
                                    config.catalog_psf_e1_column,   config.catalog_psf_e2_column};
    in.whole = std::make_unique<io::CatalogueStampSource>(run.input, run.weight, run.catalog, config.fitter.render.stamp_size, cols,
                                                          saved_ids);
  }
  if (stamp_from_header) app::validate(config);
  if (config.psf_from_catalogue && run.catalog.empty())
    throw io::ConfigError("option 'psf_input' = 'moffat_catalog' needs --catalog");
  if (run.output.empty() && !config.save_images.empty())
    throw io::ConfigError("option 'save_images' needs an output (the images go beside it)");

  // The machine must hold the run: refused now rather than swapping or killed mid-run.
  const int threads = run.threads > 0 ? run.threads : tbb::this_task_arena::max_concurrency();
  if (const auto available = io::available_memory_bytes())
    check_fit_memory(estimate_fit_memory(config, threads), *available);
  // Measured plans are chosen per process (by timing), so ranks could round differently.
  if (run.distribute && !config.fft_wisdom.empty())
    throw io::ConfigError("option 'fft_wisdom' with stampede-mpi: each rank would measure its own FFTW plans and "
                          "the rows would differ in their last bits from a single process's; run without it");
  in.planning = config.fft_wisdom.empty() ? FftPlanning::kEstimate : FftPlanning::kMeasure;
  if (!config.fft_wisdom.empty()) load_fftw_wisdom(config.fft_wisdom);  // a missing file is fine: it is made at the end
  FftPlanCache setup_plans(in.planning);
  in.recipe = std::make_shared<const StampFitterRecipe>(stamp_fitter_recipe(config, setup_plans, config.psf_from_catalogue));
  config.fitter.renderer = in.recipe->options.renderer;  // the header records the renderer auto chose
  if (!config.psf_from_catalogue) {
    if (!in.recipe->auto_note.empty()) table.warn(in.recipe->auto_note);
    // A set written by `stampede sim` or GalSim records its PSF; fitting it with another (e.g. the
    // default round Moffat) is almost always a forgotten option, and biases c by the difference.
    if (recorded_psf) {
      std::string list;
      for (const auto& d : app::psf_differences(*recorded_psf, in.recipe->psf_model)) list += (list.empty() ? "" : ", ") + d;
      if (!list.empty())
        table.warn(recorded_where + " records a PSF other than the run's: " + list +
             ". The fit uses the run's PSF; set those options to fit with the recorded one.");
    }
  }
  in.make_fitter = [recipe = in.recipe, planning = in.planning]() -> std::unique_ptr<BatchFitter> {
    return recipe->make(planning);
  };
  in.positions = run.catalog.empty() ? io::PositionColumns::kGrid : io::PositionColumns::kCatalogue;
  if (std::isfinite(in.recipe->gamma_fwhm)) {  // the reconvolution PSF the rows were fitted with
    char text[32];
    std::snprintf(text, sizeof text, "%.17g", in.recipe->gamma_fwhm);
    in.header_before.emplace_back("metacal_gamma_fwhm", text);
    in.header_types["metacal_gamma_fwhm"] = io::HeaderValueType::kReal;
  }
  in.header_before.emplace_back("INPUT", run.input);
  if (!run.catalog.empty()) in.header_before.emplace_back("CATALOG", run.catalog);
  if (!run.weight.empty()) in.header_before.emplace_back("WEIGHTS", run.weight);
  in.files = {{"input", run.input, "INDIGEST"}};
  if (!run.catalog.empty()) in.files.push_back({"catalog", run.catalog, "CATDIGST"});
  if (!run.weight.empty()) in.files.push_back({"weight", run.weight, "WGTDIGST"});
  if (config.psf_kind == PsfKind::kImage && !config.psf_from_catalogue) in.files.push_back({"psf_image", config.psf_image, "PSFDIGST"});
  if (!input_set.empty()) in.header_after.emplace_back(io::kInputSetKey, input_set);  // for `metrics` to match the truth
  return in;
}

FitInput open_survey_input(const FitRunOptions& run, const TableRun& table) {
  FitInput in;
  app::RunConfig& config = in.config;
  config = run.config;
  if (!run.input.empty() || !run.catalog.empty() || !run.weight.empty())
    throw io::ConfigError("--meds '" + run.meds[0] + "' takes no INPUT, --catalog or --weight: the tile holds the cutouts and weights");
  in.bands = survey_bands(run);
  in.meds = run.meds;
  if (!config.save_images.empty()) throw io::ConfigError("option 'save_images': not available with --meds");
  if (config.psf_from_catalogue) throw io::ConfigError("option 'psf_input' = 'moffat_catalog': not available with --meds");
  if (config.fitter.renderer == RendererKind::kUpsampled) {
    if (config.explicitly_set.count("renderer"))
      throw io::ConfigError("option 'renderer' = '" + app::get_option(config, "renderer") +
                            "': --meds needs renderer = exact (it draws through each cutout's WCS Jacobian)");
    config.fitter.renderer = RendererKind::kExact;
  }
  for (const char* key : {"noise_sigma", "stamp_size"})
    if (config.explicitly_set.count(key))
      table.warn(std::string("option '") + key + "' is not used with --meds (each cutout has its own " +
           (std::string(key) == "noise_sigma" ? "weight map" : "box size") + ")");
  if (config.meds.psf != io::MedsPsfSource::kOptions)
    for (const std::string& key : app::psf_options_set(config))
      table.warn("option '" + key + "' is not used with --meds unless meds_psf = options (each cutout's PSF " +
           "is its psf cutout or its source image's PSFEx model)");
  app::validate(config);
  const MedsFitOptions options = survey_fit_options(config);
  // A bad file fails here, before any thread starts; options a tile cannot serve likewise.
  auto source = std::make_unique<io::MedsObjectSource>(run.meds, options, options.psf_model);
  const std::vector<std::string> psfex_files = source->psfex_files();
  make_survey_fitter(config, run.meds, in.bands);
  // A `sim meds` tile names its simulation (SIMID): recorded as INSETID for `metrics` and the report
  // to refuse another simulation's truth. Tiles of two simulations are not bands of one set of
  // galaxies, though their ids and positions match.
  std::string input_set;
  std::size_t set_tile = 0;
  for (std::size_t t = 0; t < run.meds.size(); ++t) {
    std::string id;
    try {
      id = io::file_simulation_identity(run.meds[t]);
    } catch (const io::FitsError& e) {  // as a grid's record: only `metrics` and the report check it
      table.warn(std::string("the simulation's identity is unreadable, not recorded: ") + e.what());
    }
    if (!id.empty() && !input_set.empty() && id != input_set)
      throw io::ConfigError("--meds '" + run.meds[t] + "' (band " + in.bands[t] + ") is of simulation '" + id +
                            "' but --meds '" + run.meds[set_tile] + "' (band " + in.bands[set_tile] + ") of '" + input_set +
                            "': the bands of a fit must be tiles of the same galaxies");
    if (input_set.empty()) input_set = id, set_tile = t;
  }
  if (!input_set.empty()) in.header_after.emplace_back(io::kInputSetKey, input_set);
  in.locks = protect(run, table, config, psfex_files);  // every file the run reads is protected, PSFEx models included
  in.whole = std::move(source);
  in.make_fitter = [options, meds = run.meds, bands = in.bands]() -> std::unique_ptr<BatchFitter> {
    return std::make_unique<SurveyBatchFitter>(options, meds, bands);
  };
  in.positions = io::PositionColumns::kSurvey;
  // A multi-band run's further tiles as MEDS1.., their digests as MEDSDIG1.. (merge compares them).
  for (std::size_t t = 0; t < run.meds.size(); ++t) {
    const std::string k = t == 0 ? "" : std::to_string(t);
    in.header_before.emplace_back("MEDS" + k, run.meds[t]);
    in.files.push_back({"meds", run.meds[t], t == 0 ? "MEDSDIGS" : "MEDSDIG" + k});
  }
  // The PSFEx models are part of the run: a model replaced between kill and resume is refused. A
  // missing one is a flagged row, not an error, and is fingerprinted as missing.
  const std::size_t n_tiles = in.files.size();
  for (const std::string& p : psfex_files) {
    if (std::filesystem::is_regular_file(p)) in.files.push_back({"psfex", p});
    else in.fingerprint_extra += "psfex " + p + ": missing\n";
  }
  if (!psfex_files.empty())  // one key for all the models: merge compares it
    in.finish_header = [n_tiles, missing = in.fingerprint_extra](const std::vector<std::string>& digests,
                                                                  io::CatalogWriterOptions* writer_options) {
      RunFingerprint psfex;
      for (std::size_t k = n_tiles; k < digests.size(); ++k) psfex.line(digests[k]);
      writer_options->header.emplace_back("PSFEXDIG", psfex.text(missing).hex());
    };
  // The bands name the table's columns: a resume under other names is another run, not a partial
  // found corrupt at its first band column.
  if (!in.bands.empty()) in.fingerprint_extra += "bands=" + io::comma_list(in.bands) + "\n";
  return in;
}

// Tiles are told apart by content: `digests[t]` is tile t's, as the table records it (MEDSDIGS,
// MEDSDIG1, ..); S/N would be sqrt(2) too high, errors sqrt(2) too small.
void refuse_repeated_tiles(const FitInput& in, const std::vector<std::string>& digests) {
  for (std::size_t t = 1; t < in.meds.size(); ++t)
    for (std::size_t u = 0; u < t; ++u)
      if (digests[t] == digests[u])
        throw io::ConfigError("--meds '" + in.meds[t] + "' (band " + in.bands[t] + ") holds the same bytes as --meds '" +
                              in.meds[u] + "' (band " + in.bands[u] + "): " + digests[t] +
                              "; one tile per band (the same tile twice would count its pixels twice)");
}

MedsFitOptions survey_fit_options(const app::RunConfig& config) {
  MedsFitOptions options;
  static_cast<io::MedsOptions&>(options) = config.meds;
  options.fitter = config.fitter;
  options.metacal = config.metacal;
  if (config.meds.psf == io::MedsPsfSource::kOptions) {
    FftPlanCache plans(FftPlanning::kEstimate);
    options.psf_model = app::build_shared_psf(config, plans).model;
  }
  return options;
}

std::unique_ptr<BatchFitter> make_survey_fitter(const app::RunConfig& config, const std::vector<std::string>& meds,
                                                const std::vector<std::string>& bands) {
  try {
    return std::make_unique<SurveyBatchFitter>(survey_fit_options(config), meds, bands);
  } catch (const std::invalid_argument& e) {
    throw io::ConfigError(e.what());
  }
}

}  // namespace stampede::app
