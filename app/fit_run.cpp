// The fit run; see fit_run.hpp.
#include "app/fit_run.hpp"

#include <algorithm>
#include <charconv>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <memory>
#include <map>
#include <optional>
#include <set>
#include <stdexcept>
#include <vector>

#include <tbb/task_arena.h>

#include "app/survey_object_fit.hpp"
#include "app/psf_setup.hpp"
#include "app/run_fingerprint.hpp"
#include "app/run_memory.hpp"
#include "app/stamp_fitter_recipe.hpp"
#include "engine/common/number_text.hpp"
#include "engine/pipeline/pipeline.hpp"
#include "engine/pipeline/range_source.hpp"
#include "engine/pipeline/stamp_fitter.hpp"
#include "engine/render/psf_cache.hpp"
#include "engine/render/renderer_factory.hpp"
#include "io/catalog_writer.hpp"
#include "io/catalogue_source.hpp"
#include "io/durable_file.hpp"
#include "io/file_digest.hpp"
#include "io/fits_file.hpp"
#include "io/fits_error.hpp"
#include "io/grid_source.hpp"
#include "io/meds_object_source.hpp"
#include "io/output_check.hpp"
#include "io/output_lock.hpp"
#include "io/psf_keys.hpp"
#include "io/simulation_identity.hpp"
#include "io/system_memory.hpp"

namespace stampede::app {

MedsFitOptions survey_fit_options(const app::RunConfig& config);

namespace {

using Clock = std::chrono::steady_clock;

double since(Clock::time_point t) { return std::chrono::duration<double>(Clock::now() - t).count(); }

using Warn = std::function<void(const std::string&)>;
void warn_of(const FitRunOptions& run, const std::string& text) {
  if (run.on_warning) run.on_warning(text);
}

// The problems of a survey run's objects, as warnings: the first few in full, then a count at the
// end (a tile with many masked objects must not flood the terminal). Called from the writer
// thread, in input order.
class ProblemReporter {
 public:
  static constexpr int kShown = 10;
  explicit ProblemReporter(const FitRunOptions& run) : run_(run) {}
  void report(long long row, const std::string& problem) {
    if (++count_ <= kShown && run_.on_warning) run_.on_warning("object_data row " + std::to_string(row) + ": " + problem);
  }
  void finish() {
    if (count_ > kShown && run_.on_warning)
      run_.on_warning(std::to_string(count_ - kShown) + " more objects had problems (their rows' flags say which)");
  }

 private:
  const FitRunOptions& run_;
  long long count_ = 0;
};

// The output sink: appends each batch to the catalogue writer (if any), hands the rows to the
// caller, counts statuses, reports survey objects' problems in input order, and saves the data, best-fit model and residual of the objects named by
// save_images (re-rendered here from the row's parameters, on the writer thread, with its own plans).
class WriterSink final : public BatchSink {
 public:
  WriterSink(io::CatalogWriter* writer, const FitRunOptions& run, const app::RunConfig& config,
             std::shared_ptr<const PreparedPsf> shared_psf, PsfCache* psf_cache, const std::string& images_path,
             ProblemReporter* problems)
      : writer_(writer),
        run_(run),
        config_(config),
        shared_psf_(std::move(shared_psf)),
        psf_cache_(psf_cache),
        problems_(problems) {
    for (std::int64_t id : app::save_image_ids(config)) wanted_.insert(id);
    if (!wanted_.empty()) images_ = std::make_unique<io::FitsFile>(io::FitsFile::create(images_path, true));
  }
  void write(const StampBatch& batch) override {
    const std::span<const ObjectRecord> rows(batch.records.data(), batch.count);
    if (writer_) writer_->append(rows);
    if (run_.on_rows) run_.on_rows(rows);
    for (int k = 0; k < batch.count; ++k) {
      const ObjectRecord& r = batch.records[k];
      ++by_status[static_cast<int>(r.fit.status)];
      if (wanted_.count(r.id) && IsUsable(r.fit.status)) save(batch, k);
      if (!batch.problems[static_cast<std::size_t>(k)].empty())
        problems_->report(batch.first_object + k, batch.problems[static_cast<std::size_t>(k)]);
    }
  }
  std::array<long long, kFitStatusCount> by_status{};

 private:
  void save(const StampBatch& batch, int k) {
    const ObjectRecord& r = batch.records[k];
    if (!renderer_) renderer_ = make_renderer(config_.fitter.renderer, config_.fitter.render, config_.fitter.model, plans_);
    const ArenaObservation& stamp = batch.observations.first_of(k);
    std::shared_ptr<const PreparedPsf> psf = shared_psf_;
    std::string error;
    if (psf_cache_) psf = psf_cache_->get(stamp.psf, *renderer_, &error);
    if (!psf) return;
    renderer_->set_psf(psf);
    const std::span<const double> pixels = batch.observations.pixels(stamp);
    const std::size_t npix = pixels.size();
    std::vector<double> data(pixels.begin(), pixels.end()), model(npix), resid(npix);
    if (renderer_->render(r.fit.params, model) != RenderStatus::kOk) return;
    for (std::size_t i = 0; i < npix; ++i) resid[i] = data[i] - model[i];
    const std::string id = std::to_string(r.id);
    const int s = stamp.box_size;
    images_->write_image(s, s, data, "DATA_" + id);
    images_->write_image(s, s, model, "MODEL_" + id);
    images_->write_image(s, s, resid, "RESID_" + id);
  }

  io::CatalogWriter* writer_;
  const FitRunOptions& run_;
  const app::RunConfig& config_;
  std::shared_ptr<const PreparedPsf> shared_psf_;
  PsfCache* psf_cache_;
  ProblemReporter* problems_;
  std::set<std::int64_t> wanted_;
  std::unique_ptr<io::FitsFile> images_;
  FftPlanCache plans_{FftPlanning::kEstimate};
  std::unique_ptr<Renderer> renderer_;
};

// OUT.fits -> OUT.images.fits (any other name: NAME.images.fits).
std::string images_path_for(std::string output) {
  if (output.size() > 5 && output.compare(output.size() - 5, 5, ".fits") == 0) output.resize(output.size() - 5);
  return output + ".images.fits";
}

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

// The outputs, checked before anything is read (a refused one costs nothing) and locked so that no
// other run can write them until these locks are released, after the writer is done.
std::vector<io::OutputLock> lock_outputs(const FitRunOptions& run, const app::RunConfig& config,
                                         const std::vector<std::string>& psfex_files = {}) {
  std::vector<io::OutputLock> locks;
  if (run.output.empty()) return locks;
  io::check_outputs(outputs_of(run, config), inputs_of(run, config, psfex_files), run.overwrite || run.resume);
  locks.push_back(io::OutputLock::acquire(run.output));
  if (!run.text_output.empty()) locks.push_back(io::OutputLock::acquire(run.text_output));
  return locks;
}

// The pipeline's counts and the phases' times into the run's summary.
void add_pipeline_figures(const PipelineSummary& fitted, const std::array<long long, kFitStatusCount>& by_status,
                          Clock::time_point start, Clock::time_point finish_start, RunSummary* summary) {
  summary->by_status = by_status;
  summary->objects = fitted.objects;
  summary->batches = fitted.batches;
  summary->threads = fitted.threads;
  summary->pipeline_seconds = fitted.seconds;
  summary->finish_seconds = since(finish_start);
  summary->total_seconds = since(start);
}

// The pipeline's progress as the run reports it: every progress_interval seconds at most, counting
// the resumed objects as done.
std::function<void(const PipelineProgress&)> progress_reporter(const FitRunOptions& run, long long total,
                                                               long long done_before) {
  return [&run, total, done_before, last_report = -1.0](const PipelineProgress& p) mutable {
    if (!run.on_progress || p.seconds - last_report < run.progress_interval) return;
    last_report = p.seconds;
    FitRunProgress r;
    r.objects_done = done_before + p.objects_done;
    r.objects_total = total;
    r.seconds = p.seconds;
    r.objects_per_second = p.objects_done / std::max(p.seconds, 1e-9);
    r.eta_seconds = (total - r.objects_done) / std::max(r.objects_per_second, 1e-9);
    run.on_progress(r);
  };
}

// Writer options every run's table shares: the path, the effective options as typed header keys.
io::CatalogWriterOptions base_writer_options(const FitRunOptions& run, const app::RunConfig& config) {
  io::CatalogWriterOptions writer_options;
  writer_options.path = run.output;
  writer_options.text_path = run.text_output;
  writer_options.header = app::effective_options(config);
  for (const io::OptionInfo& o : app::run_config_options())
    if (o.type != io::HeaderValueType::kText) writer_options.header_types[o.name] = o.type;
  return writer_options;
}

// Adds the shard's keys after the fingerprint's lines, and to it: a shard resumes only as that shard.
void add_shard_keys(const FitRunOptions& run, long long input_objects, io::CatalogWriterOptions* writer_options) {
  if (run.shards <= 1) return;
  writer_options->header.emplace_back(kShardKey, shard_text(run.shard, run.shards));
  writer_options->header.emplace_back(kShardTotalKey, std::to_string(input_objects));
  writer_options->header_types[kShardTotalKey] = io::HeaderValueType::kInteger;
  writer_options->fingerprint += "shard " + std::to_string(run.shard) + "/" + std::to_string(run.shards) + " of " +
                     std::to_string(input_objects) + "\n";
}

// After the fingerprint and the shard keys: each file's identity under its digest key (what merge
// compares, not the path as typed) and RUNFP, the whole fingerprint's hash (what a complete
// output's resume compares). `digests` as fit_fingerprint gave them for `files`.
void add_identity_keys(const std::vector<FingerprintFile>& files, const std::vector<std::string>& digests,
                       io::CatalogWriterOptions* writer_options) {
  for (std::size_t k = 0; k < files.size(); ++k)
    if (!files[k].digest_key.empty()) writer_options->header.emplace_back(files[k].digest_key, digests[k]);
  writer_options->header.emplace_back(kRunFingerprintKey, RunFingerprint().text(writer_options->fingerprint).hex());
}

// skip_if_complete: true when a.output is already this run's complete table (its RUNFP is this
// run's), so that the run is skipped; throws io::ConfigError naming it when it is another run's.
bool output_is_this_complete_run(const FitRunOptions& run, const io::CatalogWriterOptions& writer_options) {
  if (!run.resume || !run.skip_if_complete) return false;
  std::string mine;
  for (const auto& [k, v] : writer_options.header)
    if (k == kRunFingerprintKey) mine = v;
  return is_this_runs_complete_table(run.output, "RESULTS", mine);
}


// What an input gives the run path: its source (and shard), the configuration as the input made it,
// the fit stage's factory, and what the table records of the input.
struct RunInput {
  app::RunConfig config;
  std::unique_ptr<StampSource> whole;  // the input
  std::unique_ptr<StampSource> shard;  // its shard's range (--shard), or null
  StampSource& source() { return shard ? *shard : *whole; }
  long long objects = 0;               // the whole input's
  std::vector<io::OutputLock> locks;   // held until the writer is done
  std::function<std::unique_ptr<BatchFitter>()> make_fitter;
  std::vector<std::string> meds, bands;  // survey input: for the workers of a distributed run
  FftPlanning planning = FftPlanning::kEstimate;
  std::shared_ptr<const StampFitterRecipe> recipe;  // stamp input: its fitters' recipe (and PSF, for save_images)
  // The table: its positions' columns; keys before the fingerprint; the files fingerprinted and
  // a text the fingerprint adds; keys after it; and a last step given the files' digests.
  io::PositionColumns positions = io::PositionColumns::kGrid;
  std::vector<std::pair<std::string, std::string>> header_before, header_after;
  std::map<std::string, io::HeaderValueType> header_types;
  std::vector<FingerprintFile> files;
  std::string fingerprint_extra;
  std::function<void(const std::vector<std::string>& digests, io::CatalogWriterOptions*)> finish_header;
};

// A shard reads only its range of the input (the whole input's source stays alive beside it).
void take_shard(const FitRunOptions& run, RunInput* in) {
  in->objects = in->whole->total_objects();
  if (run.shards <= 1) return;
  if (in->objects < 0) throw io::ConfigError("--shard needs an input whose object count is known");
  const ShardRange range = shard_range(in->objects, run.shard, run.shards);
  in->shard = std::make_unique<RangeSource>(*in->whole, range.begin, range.end);
}

// What a grid's header says of itself, used as a user expects: the PSF it records (unless the run
// sets one), its noise (NOISESIG, unless the run sets noise_sigma or gives a weight map), the
// simulated set it is (*input_set), and its noise pairs (NOISEPR, for metacal's fixnoise fields).
void use_grid_records(const FitRunOptions& run, io::GridStampSource& grid, const Warn& warn, app::RunConfig* config,
                      std::optional<PsfModel>* recorded_psf, std::string* input_set) {
  const std::string where = grid.header().describe();
  try {
    *recorded_psf = io::read_psf_keys_if_present(grid.header());
  } catch (const io::FitsError& e) {  // the record is a convenience: the fit does not need it
    warn(std::string("the PSF record is unreadable, neither used nor checked: ") + e.what());
  }
  if (*recorded_psf && !app::sets_psf_options(*config)) app::use_recorded_psf(**recorded_psf, where, config);
  if (run.weight.empty() && !config->explicitly_set.count("noise_sigma")) {
    std::optional<double> sigma;
    try {
      sigma = grid.header().read_key_double("NOISESIG");
    } catch (const io::FitsError& e) {
      warn(std::string("the NOISESIG record is unreadable, not used: ") + e.what());
    }
    if (sigma && std::isfinite(*sigma) && *sigma > 0) {
      config->fitter.noise_sigma = *sigma;
      config->explicitly_set["noise_sigma"] = "";  // as if the run had set it
      warn("noise_sigma = " + number_text(*sigma) + " taken from " + where +
           " NOISESIG (the run sets none; set noise_sigma to override)");
    } else if (sigma && !(std::isfinite(*sigma) && *sigma >= 0)) {
      warn(where + " NOISESIG = " + number_text(*sigma) + " is not a noise level, not used");
    }
  }
  try {
    *input_set = io::simulation_identity(grid.header());
  } catch (const io::FitsError& e) {  // as the PSF record: only `metrics` checks it
    warn(std::string("the simulated set's identity is unreadable, not recorded: ") + e.what());
  }
  if (config->metacal.enabled && config->metacal.fixnoise) {  // a set simulated in noise pairs pairs its fixnoise fields
    std::optional<std::string> pairs;
    try {
      pairs = grid.header().read_key_string("NOISEPR");
    } catch (const io::FitsError& e) {
      warn(std::string("the NOISEPR record is unreadable, fixnoise fields not paired: ") + e.what());
    }
    config->metacal.noise_pairs = pairs && *pairs == "T";
  }
}

// A grid of stamps, or an image with a catalogue of objects to cut from it.
RunInput open_stamp_input(const FitRunOptions& run, const Warn& warn) {
  RunInput in;
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
  in.locks = lock_outputs(run, config);  // before anything is read: a refused output costs nothing

  // Input first: its header may fix the stamp size, and a bad file should fail before anything.
  std::optional<PsfModel> recorded_psf;
  std::string recorded_where, input_set;
  if (run.catalog.empty()) {
    auto grid = std::make_unique<io::GridStampSource>(run.input, run.weight, stamp_from_header ? 0 : config.fitter.render.stamp_size);
    config.fitter.render.stamp_size = grid->stamp_size();
    recorded_where = grid->header().describe();
    use_grid_records(run, *grid, warn, &config, &recorded_psf, &input_set);
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
  take_shard(run, &in);
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
    if (!in.recipe->auto_note.empty()) warn(in.recipe->auto_note);
    // A set written by `stampede sim` or GalSim records its PSF; fitting it with another (e.g. the
    // default round Moffat) is almost always a forgotten option, and biases c by the difference.
    if (recorded_psf) {
      std::string list;
      for (const auto& d : app::psf_differences(*recorded_psf, in.recipe->psf_model)) list += (list.empty() ? "" : ", ") + d;
      if (!list.empty())
        warn(recorded_where + " records a PSF other than the run's: " + list +
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

// MEDS tiles, one per band: each object's cutouts read in the serial stage (io/meds_object_source).
RunInput open_survey_input(const FitRunOptions& run, const Warn& warn) {
  RunInput in;
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
      warn(std::string("option '") + key + "' is not used with --meds (each cutout has its own " +
           (std::string(key) == "noise_sigma" ? "weight map" : "box size") + ")");
  if (config.meds.psf != io::MedsPsfSource::kOptions)
    for (const std::string& key : app::psf_options_set(config))
      warn("option '" + key + "' is not used with --meds unless meds_psf = options (each cutout's PSF " +
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
      warn(std::string("the simulation's identity is unreadable, not recorded: ") + e.what());
    }
    if (!id.empty() && !input_set.empty() && id != input_set)
      throw io::ConfigError("--meds '" + run.meds[t] + "' (band " + in.bands[t] + ") is of simulation '" + id +
                            "' but --meds '" + run.meds[set_tile] + "' (band " + in.bands[set_tile] + ") of '" + input_set +
                            "': the bands of a fit must be tiles of the same galaxies");
    if (input_set.empty()) input_set = id, set_tile = t;
  }
  if (!input_set.empty()) in.header_after.emplace_back(io::kInputSetKey, input_set);
  in.locks = lock_outputs(run, config, psfex_files);  // every file the run reads is protected, PSFEx models included
  in.whole = std::move(source);
  take_shard(run, &in);
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
  if (!in.bands.empty()) {
    std::string names;
    for (const std::string& b : in.bands) names += (names.empty() ? "" : ",") + b;
    in.fingerprint_extra += "bands=" + names + "\n";
  }
  return in;
}

// The same tile given as two bands (another spelling of its path, a link, a copy, "g.fits[0]")
// would count its pixels twice: S/N sqrt(2) too high, errors sqrt(2) too small. Tiles are told
// apart by content: `digests[t]` is tile t's, as the table records it (MEDSDIGS, MEDSDIG1, ..).
void refuse_repeated_tiles(const RunInput& in, const std::vector<std::string>& digests) {
  for (std::size_t t = 1; t < in.meds.size(); ++t)
    for (std::size_t u = 0; u < t; ++u)
      if (digests[t] == digests[u])
        throw io::ConfigError("--meds '" + in.meds[t] + "' (band " + in.bands[t] + ") holds the same bytes as --meds '" +
                              in.meds[u] + "' (band " + in.bands[u] + "): " + digests[t] +
                              "; one tile per band (the same tile twice would count its pixels twice)");
}

// The table's writer (created, or resumed with the source moved past the committed rows); null
// without an output, or when the output is already this complete run's (*skipped).
std::unique_ptr<io::CatalogWriter> open_writer(const FitRunOptions& run, RunInput& in, RunSummary* summary) {
  if (run.output.empty()) {
    if (in.meds.size() > 1) {  // no table records the tiles' digests: they are read for this check alone
      std::vector<std::string> digests;
      for (const std::string& tile : in.meds) digests.push_back(io::digest_file(io::fits_root_name(tile)).text());
      refuse_repeated_tiles(in, digests);
    }
    return nullptr;
  }
  io::CatalogWriterOptions writer_options = base_writer_options(run, in.config);
  writer_options.positions = in.positions;
  writer_options.metacal = in.config.metacal.enabled;
  writer_options.bands = in.bands;
  for (const auto& [key, type] : in.header_types) writer_options.header_types[key] = type;
  writer_options.header.insert(writer_options.header.end(), in.header_before.begin(), in.header_before.end());
  std::vector<std::string> digests;
  writer_options.fingerprint = fit_fingerprint(in.files, writer_options.header, &digests) + in.fingerprint_extra;
  refuse_repeated_tiles(in, digests);  // a survey run's files begin with its tiles, in order
  writer_options.header.insert(writer_options.header.end(), in.header_after.begin(), in.header_after.end());
  add_shard_keys(run, in.objects, &writer_options);
  add_identity_keys(in.files, digests, &writer_options);
  if (in.finish_header) in.finish_header(digests, &writer_options);
  if (output_is_this_complete_run(run, writer_options)) {
    summary->skipped = true;
    return nullptr;
  }
  if (!run.resume) return io::CatalogWriter::create(writer_options);
  bool started = false;
  std::unique_ptr<io::CatalogWriter> writer = io::CatalogWriter::resume(writer_options, &summary->resumed, &started);
  if (started) warn_of(run, "nothing to resume at " + run.output + ": no object was committed; the run starts from the first");
  in.source().skip_to(summary->resumed);
  return writer;
}

// The one run path of every input: the writer, the pipeline (here or distributed), the finish.
RunSummary run_input(const FitRunOptions& run, RunInput& in, Clock::time_point start) {
  const app::RunConfig& config = in.config;
  RunSummary summary;
  summary.input = run.meds.empty() ? run.input : run.meds[0];
  for (std::size_t t = 1; t < run.meds.size(); ++t) summary.input += "," + run.meds[t];
  summary.catalog = run.catalog;
  summary.weight = run.weight;
  summary.output = run.output;
  summary.text_output = run.text_output;
  std::unique_ptr<io::CatalogWriter> writer = open_writer(run, in, &summary);
  if (summary.skipped) return summary;
  // A run that fails with an error leaves no partial output, unless a write ran out of room after
  // rows were committed (the writer keeps them for --resume); a killed one leaves it for --resume.
  const std::string images_path = images_path_for(run.output);
  ProblemReporter problems(run);
  try {
    WriterSink sink(writer.get(), run, config, in.recipe ? in.recipe->shared_psf : nullptr,
                    in.recipe ? in.recipe->psf_cache.get() : nullptr, images_path, &problems);
    PipelineOptions pipeline_options;
    pipeline_options.threads = run.threads;
    pipeline_options.batch_size = config.batch_size;
    pipeline_options.stop = run.stop;
    std::function<std::unique_ptr<BatchFitter>()> make_fitter = in.make_fitter;
    if (run.distribute) {
      FitDistribution d = run.distribute(DistributedRun{config, in.meds, in.bands}, make_fitter);
      make_fitter = std::move(d.make_fitter);
      pipeline_options.threads = d.pipeline_threads;
    }
    summary.setup_seconds = since(start);
    const PipelineSummary fitted = run_pipeline(in.source(), sink, make_fitter, pipeline_options,
                                                progress_reporter(run, in.source().total_objects(), summary.resumed));
    const Clock::time_point finish_start = Clock::now();
    summary.interrupted = fitted.stopped;
    if (writer && !fitted.stopped) writer->finish();  // stopped: the partials stay, as a kill leaves them
    if (in.recipe && !config.fft_wisdom.empty() && !save_fftw_wisdom(config.fft_wisdom) && !run.quiet)
      warn_of(run, "could not write FFTW wisdom to '" + config.fft_wisdom + "'");
    problems.finish();
    add_pipeline_figures(fitted, sink.by_status, start, finish_start, &summary);
    return summary;
  } catch (...) {
    if (writer) writer->abandon();
    if (writer && !config.save_images.empty()) io::remove_if_present(images_path);
    throw;
  }
}

}  // namespace

std::string FitRunProgress::Line() const {
  char buf[160];
  std::snprintf(buf, sizeof buf, "%lld/%lld objects (%.1f%%), %.1f objects/s, ETA %.0f s   ", objects_done,
                objects_total, 100.0 * objects_done / std::max(objects_total, 1LL), objects_per_second, eta_seconds);
  return buf;
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

RunSummary FitRun::run() const {
  const Clock::time_point start = Clock::now();
  const FitRunOptions& run = options_;
  check_threads(run.threads, "threads");
  if (run.output.empty() && run.resume) throw std::invalid_argument("fit run: resume needs the output to resume");
  shard_range(0, run.shard, run.shards);  // checks the shard before anything is read
  const Warn warn = [&run](const std::string& text) { warn_of(run, text); };
  RunInput input = run.meds.empty() ? open_stamp_input(run, warn) : open_survey_input(run, warn);
  return run_input(run, input, start);
}

}  // namespace stampede::app
