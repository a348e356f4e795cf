// The fit run; see fit_run.hpp.
#include "app/fit_run.hpp"

#include <chrono>
#include <memory>
#include <stdexcept>
#include <vector>

#include "app/fit_input.hpp"
#include "app/fit_table_sink.hpp"
#include "app/worker_recipe.hpp"
#include "io/catalog_writer.hpp"
#include "io/durable_file.hpp"
#include "io/file_digest.hpp"
#include "io/fits_file.hpp"

namespace stampede::app {
namespace {

using Clock = std::chrono::steady_clock;

double since(Clock::time_point t) { return std::chrono::duration<double>(Clock::now() - t).count(); }

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

// The table's writer (created, or resumed: *committed), with the run's identity in its header; null
// without an output, or when the output is already this complete run's.
std::unique_ptr<io::CatalogWriter> open_writer(const FitRunOptions& run, const TableRun& table, FitInput& in,
                                               long long* committed) {
  if (run.output.empty()) {
    if (in.meds.size() > 1) {  // no table records the tiles' digests: they are read for this check alone
      std::vector<std::string> digests;
      for (const std::string& tile : in.meds) digests.push_back(io::digest_file(io::fits_root_name(tile)).text());
      refuse_repeated_tiles(in, digests);
    }
    return nullptr;
  }
  io::CatalogWriterOptions writer_options;
  writer_options.path = run.output;
  writer_options.text_path = run.text_output;
  writer_options.header = app::effective_options(in.config);
  for (const io::OptionInfo& o : app::run_config_options())
    if (o.type != io::HeaderValueType::kText) writer_options.header_types[o.name] = o.type;
  writer_options.positions = in.positions;
  writer_options.metacal = in.config.metacal.enabled;
  writer_options.bands = in.bands;
  for (const auto& [key, type] : in.header_types) writer_options.header_types[key] = type;
  writer_options.header.insert(writer_options.header.end(), in.header_before.begin(), in.header_before.end());
  std::vector<std::string> digests;
  writer_options.fingerprint = fit_fingerprint(in.files, writer_options.header, &digests) + in.fingerprint_extra;
  refuse_repeated_tiles(in, digests);  // a survey run's files begin with its tiles, in order
  writer_options.header.insert(writer_options.header.end(), in.header_after.begin(), in.header_after.end());
  // Each file's identity under its digest key: what merge compares, not the path as typed.
  for (std::size_t k = 0; k < in.files.size(); ++k)
    if (!in.files[k].digest_key.empty()) writer_options.header.emplace_back(in.files[k].digest_key, digests[k]);
  if (in.finish_header) in.finish_header(digests, &writer_options);
  seal_identity(table, in.whole->total_objects(), &writer_options, kShardTotalKey);
  std::unique_ptr<io::CatalogWriter> writer = open_table<io::CatalogWriter>(table, writer_options);
  if (writer) *committed = writer->units();
  return writer;
}

// The one run path of every input: the writer, the pipeline (here or distributed), the finish.
RunSummary run_input(const FitRunOptions& run, const TableRun& table, FitInput& in, Clock::time_point start) {
  const app::RunConfig& config = in.config;
  RunSummary summary;
  summary.input = run.meds.empty() ? run.input : run.meds[0];
  for (std::size_t t = 1; t < run.meds.size(); ++t) summary.input += "," + run.meds[t];
  summary.catalog = run.catalog;
  summary.weight = run.weight;
  summary.output = run.output;
  summary.text_output = run.text_output;
  std::unique_ptr<io::CatalogWriter> writer = open_writer(run, table, in, &summary.resumed);
  if (!writer && !run.output.empty()) {
    summary.skipped = true;
    return summary;
  }
  const std::unique_ptr<StampSource> shard = shard_source(table, *in.whole, summary.resumed);
  StampSource& source = shard ? *shard : *in.whole;
  const std::string images_path = images_path_for(run.output);
  try {
    FitTableSink sink(writer.get(), run, config, in.recipe ? in.recipe->shared_psf : nullptr,
                      in.recipe ? in.recipe->psf_cache.get() : nullptr, images_path);
    PipelineOptions pipeline_options;
    pipeline_options.threads = run.threads;
    pipeline_options.batch_size = config.batch_size;
    summary.setup_seconds = since(start);
    const PipelineSummary fitted = measure_table(table, source, summary.resumed, sink, writer.get(), in.make_fitter,
                                                 pipeline_options, fit_worker_recipe(config, in.meds, in.bands));
    const Clock::time_point finish_start = Clock::now();
    summary.interrupted = fitted.stopped;
    if (in.recipe && !config.fft_wisdom.empty() && !save_fftw_wisdom(config.fft_wisdom) && !run.quiet)
      table.warn("could not write FFTW wisdom to '" + config.fft_wisdom + "'");
    sink.report_remaining_problems();
    add_pipeline_figures(fitted, sink.by_status, start, finish_start, &summary);
    return summary;
  } catch (...) {
    if (writer && !config.save_images.empty()) io::remove_if_present(images_path);
    throw;
  }
}

}  // namespace

RunSummary FitRun::run() const {
  const Clock::time_point start = Clock::now();
  const FitRunOptions& run = options_;
  check_threads(run.threads, "threads");
  if (run.output.empty() && run.resume) throw std::invalid_argument("fit run: resume needs the output to resume");
  shard_range(0, run.shard, run.shards);  // checks the shard before anything is read
  const TableRun table = table_run(run, "RESULTS", "object");
  FitInput input = run.meds.empty() ? open_stamp_input(run, table) : open_survey_input(run, table);
  return run_input(run, table, input, start);
}

}  // namespace stampede::app
