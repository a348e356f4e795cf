// A metadetection run; see metadetect_run.hpp.
#include "app/metadetect_run.hpp"

#include <algorithm>
#include <stdexcept>
#include <chrono>
#include <memory>
#include <optional>

#include "app/metadetect_input.hpp"
#include "app/run_harness.hpp"
#include "engine/metadetect/cell_batch.hpp"
#include "engine/metadetect/cell_batch_measurer.hpp"
#include "engine/metadetect/sep_detection.hpp"
#include "engine/pipeline/pipeline.hpp"
#include "io/cell_source.hpp"
#include "io/config_error.hpp"
#include "io/fits_file.hpp"
#include "io/metadetect_package_layout.hpp"
#include "io/metadetect_reader.hpp"
#include "io/metadetect_writer.hpp"
#include "io/output_check.hpp"
#include "io/output_lock.hpp"

namespace stampede::app {
namespace {

constexpr int kMaxProblems = 100;

class CellSink : public BatchSink {
 public:
  CellSink(io::MetadetectWriter& writer, const io::CellSource& source, MetadetectRunSummary* summary)
      : writer_(writer), source_(source), summary_(summary) {}
  void write(const StampBatch& batch) override {
    const CellBatch& data = batch.payload<CellBatch>();
    writer_.append(data.rows, batch.count);
    summary_->cells += batch.count;
    summary_->rows += static_cast<long long>(data.rows.size());
    for (int k = 0; k < batch.count; ++k) {
      const std::string& p = data.problems[static_cast<std::size_t>(k)];
      if (p.empty()) continue;
      ++summary_->cells_failed;
      if (summary_->problems.size() < kMaxProblems)
        summary_->problems.push_back(source_.input(data.cells[static_cast<std::size_t>(k)].file) + " cell " +
                                     std::to_string(batch.records[k].id) + ": " + p);
    }
  }

 private:
  io::MetadetectWriter& writer_;
  const io::CellSource& source_;
  MetadetectRunSummary* summary_;
};

// Python's: the rows kept in memory.
class CollectingSink : public BatchSink {
 public:
  void write(const StampBatch& batch) override {
    const CellBatch& data = batch.payload<CellBatch>();
    rows.insert(rows.end(), data.rows.begin(), data.rows.end());
    for (const std::string& p : data.problems) failed += !p.empty();
  }
  std::vector<MetadetectRow> rows;
  long long failed = 0;
};

// The run's outputs (the table, and a job's parts: stampede-mpi's ranks') and every file it reads.
std::vector<io::RunOutput> outputs_of(const MetadetectRunOptions& options, const std::vector<std::string>& parts) {
  std::vector<io::RunOutput> outputs = {table_output("-o", options.output)};
  if (!options.package_output.empty()) outputs.push_back(table_output("--package-output", options.package_output));
  for (const std::string& part : parts) outputs.push_back(table_output("-o (a rank's part)", part));
  return outputs;
}
std::vector<io::RunInput> inputs_of(const MetadetectRunOptions& options, const MetadetectFiles& read) {
  std::vector<io::RunInput> inputs;
  for (const std::string& in : read.files) inputs.push_back({"input", io::fits_root_name(in)});
  for (const std::string& p : read.images.psfex) inputs.push_back({"--psfex", p});
  if (!options.star_mask.empty()) inputs.push_back({"--star-mask", io::fits_root_name(options.star_mask)});
  return inputs;
}

// The complete table's rows rewritten in the reference package's layout, its primary header
// naming the table and its run.
void write_package_output(const MetadetectRunOptions& options, const MetadetectOptions& measure,
                          const std::vector<std::string>& bands) {
  if (options.package_output.empty()) return;
  io::MetadetectRowReader reader(options.output);
  io::PackageLayoutOptions layout;
  layout.measurement = metadetect_measurement_name(measure.measurement);
  layout.bands = std::max<int>(1, static_cast<int>(bands.size()));
  layout.shear_bands = io::package_band_indices(measure.shear_bands, layout.bands);
  layout.det_bands = io::package_band_indices(measure.detect_bands, layout.bands);
  std::vector<std::pair<std::string, std::string>> keys = {{"TABLE", options.output}};
  {
    io::FitsFile f = io::FitsFile::open_read(options.output);
    f.move_to("METADETECT");
    for (const char* key : {"RUNFP", "MEASURE", "BANDS", "DETBANDS", "SHRBANDS", "NCELLS"})
      if (const std::optional<std::string> v = f.read_key_string(key)) keys.emplace_back(key, *v);
  }
  io::write_package_layout(options.package_output, reader, layout, keys);
}

}  // namespace

void write_metadetect_package_output(const MetadetectRunOptions& options) {
  const std::vector<std::string> bands = metadetect_bands(options);
  MetadetectOptions measure = options.metadetect;
  measure.detect_bands = band_role_mask(options.detect_bands, bands, "--detect-bands");
  measure.shear_bands = band_role_mask(options.shear_bands, bands, "--shear-bands");
  write_package_output(options, measure, bands);
}

void check_metadetect_outputs(const MetadetectRunOptions& options, const std::vector<std::string>& parts) {
  io::check_outputs(outputs_of(options, parts), inputs_of(options, metadetect_files(options, metadetect_bands(options))),
                    options.overwrite || options.resume);
}

std::vector<MetadetectRow> metadetect_image(std::span<const io::CellImage> bands, const MetadetectOptions& options,
                                            int threads,
                                            long long* cells_failed) {
  std::string why;
  if (!options.IsValid(&why)) throw io::ConfigError(why);
  io::CellSource source(bands, options);
  CollectingSink sink;
  set_detection_pixel_stack(static_cast<long long>(options.cell_size) * options.cell_size);
  PipelineOptions pipeline_options;
  pipeline_options.threads = threads;
  pipeline_options.batch_size = 2;
  run_pipeline(source, sink, [&] { return std::make_unique<CellBatchMeasurer>(options); }, pipeline_options);
  if (cells_failed) *cells_failed = sink.failed;
  return std::move(sink.rows);
}

MetadetectRunSummary run_metadetect(const MetadetectRunOptions& options) {
  using Clock = std::chrono::steady_clock;
  const Clock::time_point start = Clock::now();
  std::string why;
  if (!options.metadetect.IsValid(&why)) throw io::ConfigError(why);
  if (options.inputs.empty()) throw io::ConfigError("no input image: give IMAGE.fits or --input-list");
  if (options.output.empty()) throw io::ConfigError("no output: give -o OUT.fits");
  if (options.cells_per_batch < 1) throw io::ConfigError("cells per batch must be >= 1");
  shard_range(0, options.shard, options.shards);  // checks the shard before anything is read
  if (!options.package_output.empty() && options.shards > 1)
    throw io::ConfigError("--package-output with --shard: a shard's table is a part of the run; write the package's "
                          "layout from the whole table");
  const TableRun table = table_run(options, "METADETECT", "cell");
  const std::vector<std::string> bands = metadetect_bands(options);
  MetadetectOptions measure = options.metadetect;
  measure.detect_bands = band_role_mask(options.detect_bands, bands, "--detect-bands");
  measure.shear_bands = band_role_mask(options.shear_bands, bands, "--shear-bands");
  const MetadetectFiles read = metadetect_files(options, bands);
  const std::vector<io::OutputLock> locks = protect_outputs(table, outputs_of(options, {}), inputs_of(options, read));

  io::CellSource source = open_cell_source(options, measure, read);
  io::MetadetectWriterOptions writer_options =
      metadetect_table_options(options, bands, measure, read, source.total_objects());
  seal_identity(table, source.total_objects(), &writer_options);
  // SEP's pixel stack is global: sized for a whole cell above the threshold before threads start.
  set_detection_pixel_stack(source.max_cell_pixels());

  MetadetectRunSummary summary;
  std::unique_ptr<io::MetadetectWriter> writer = open_table<io::MetadetectWriter>(table, writer_options);
  if (!writer) {
    summary.skipped = true;
    write_package_output(options, measure, bands);
    return summary;
  }
  summary.cells_resumed = writer->units();
  const std::unique_ptr<StampSource> shard = shard_source(table, source, summary.cells_resumed);
  CellSink sink(*writer, source, &summary);
  PipelineOptions pipeline_options;
  pipeline_options.threads = options.threads;
  pipeline_options.batch_size = options.cells_per_batch;
  const PipelineSummary ran =
      measure_table(table, shard ? *shard : source, summary.cells_resumed, sink, writer.get(),
                    [&] { return std::make_unique<CellBatchMeasurer>(measure); }, pipeline_options);
  summary.threads = ran.threads;
  summary.stopped = ran.stopped;
  writer.reset();
  if (!ran.stopped) write_package_output(options, measure, bands);
  summary.seconds = std::chrono::duration<double>(Clock::now() - start).count();
  return summary;
}

}  // namespace stampede::app
