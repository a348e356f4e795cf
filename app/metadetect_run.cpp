// A metadetection run; see metadetect_run.hpp.
#include "app/metadetect_run.hpp"

#include <tbb/task_arena.h>

#include <algorithm>
#include <stdexcept>
#include <chrono>
#include <memory>

#include "app/metadetect_option_keys.hpp"
#include "app/run_fingerprint.hpp"
#include "app/run_harness.hpp"
#include "app/version.hpp"
#include "engine/metadetect/cell_batch.hpp"
#include "engine/metadetect/cell_batch_measurer.hpp"
#include "engine/metadetect/sep_detection.hpp"
#include "engine/pipeline/pipeline.hpp"
#include "io/cell_image_reader.hpp"
#include "io/cell_source.hpp"
#include "io/config_error.hpp"
#include "io/file_digest.hpp"
#include "io/metadetect_writer.hpp"
#include "io/output_check.hpp"
#include "io/output_lock.hpp"
#include "io/result_columns.hpp"

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

// What stands for the band's name in an image path or --psfex.
constexpr std::string_view kBandField = "{band}";

bool has_band_field(const std::string& path) { return path.find(kBandField) != std::string::npos; }

std::vector<std::string> image_bands(const MetadetectRunOptions& options);

}  // namespace

std::string expand_band(const std::string& path, const std::string& band) {
  std::string out = path;
  for (std::size_t at = out.find(kBandField); at != std::string::npos; at = out.find(kBandField, at + band.size()))
    out.replace(at, kBandField.size(), band);
  return out;
}

namespace {

// Image files' bands: --bands names what `{band}` stands for in every path.
std::vector<std::string> image_bands(const MetadetectRunOptions& options) {
  std::vector<std::pair<std::string, std::string>> templates;  // (what, path)
  for (const std::string& in : options.inputs) templates.emplace_back("image path", in);
  if (!options.psfex.empty()) templates.emplace_back("--psfex", options.psfex);
  const std::vector<std::string>& names = options.bands;
  const std::size_t n = names.size();
  if (n == 0) {
    for (const auto& [what, path] : templates)
      if (has_band_field(path))
        throw io::ConfigError(what + " '" + path + "' holds '{band}' but no --bands names the bands it stands for");
    return {};
  }
  if (n > static_cast<std::size_t>(kMaxMetadetectBands))
    throw io::ConfigError("--bands names " + std::to_string(n) + " bands: at most " + std::to_string(kMaxMetadetectBands));
  if (std::string why; !io::are_band_names(names, &why)) throw io::ConfigError("--bands: " + why);
  if (n > 1) {
    for (const auto& [what, path] : templates)
      if (!has_band_field(path))
        throw io::ConfigError("--bands names " + std::to_string(n) + " bands but " + what + " '" + path +
                              "' holds no '{band}': each is a template, read once per band with {band} its name");
    for (const std::string& in : options.inputs)
      for (std::size_t b = 0; b < n; ++b)
        for (std::size_t a = 0; a < b; ++a)
          if (io::same_file(expand_band(in, names[a]), expand_band(in, names[b])))
            throw io::ConfigError("image " + expand_band(in, names[b]) + " is bands " + names[a] + " and " + names[b] +
                                  " of '" + in + "'");
  }
  return names;
}

// What measures one band only, whichever input carries the bands; `give` says how to give one.
void refuse_bands_for_one_band_measurements(const MetadetectOptions& o, std::size_t bands, const std::string& give) {
  if (bands < 2) return;
  if (o.per_object_metacal) throw io::ConfigError("--per-object-metacal measures one band: " + give);
  if (is_model_fit(o.measurement))
    throw io::ConfigError(std::string("--measurement ") + metadetect_measurement_name(o.measurement) +
                          " fits one band: " + give + ", or measure the bands with wmom or pgauss");
}

}  // namespace

std::vector<std::string> metadetect_bands(const MetadetectRunOptions& options) {
  if (!options.tile) {
    std::vector<std::string> names = image_bands(options);
    refuse_bands_for_one_band_measurements(options.metadetect, names.size(), "give --bands one band");
    return names;
  }
  if (!options.psfex.empty())
    throw io::ConfigError("--psfex gives image files' PSF: a --meds cell tile has its own PSF cutouts");
  const std::size_t n = options.inputs.size();
  if (n > static_cast<std::size_t>(kMaxMetadetectBands))
    throw io::ConfigError(std::to_string(n) + " --meds tiles: at most " + std::to_string(kMaxMetadetectBands) + " bands");
  if (!options.bands.empty() && options.bands.size() != n)
    throw io::ConfigError("--bands names " + std::to_string(options.bands.size()) + " band" +
                          (options.bands.size() == 1 ? "" : "s") + " but " + std::to_string(n) + " --meds tile" +
                          (n == 1 ? " is" : "s are") + " given: one tile per band, in the order of --bands");
  if (options.bands.empty() && n == 1) return {};
  std::vector<std::string> names = options.bands;
  if (names.empty())
    for (std::size_t b = 0; b < n; ++b) {
      // Appended, not "b" + to_string(b): GCC 12 warns (-Wrestrict) falsely on that concatenation.
      std::string name = "b";
      name += std::to_string(b);
      names.push_back(std::move(name));
    }
  if (std::string why; !io::are_band_names(names, &why)) throw io::ConfigError("--bands: " + why);
  for (std::size_t b = 0; b < n; ++b)
    for (std::size_t a = 0; a < b; ++a)
      if (io::same_file(options.inputs[a], options.inputs[b]))
        throw io::ConfigError("--meds " + options.inputs[b] + " is given twice (bands " + names[a] + " and " + names[b] + ")");
  refuse_bands_for_one_band_measurements(options.metadetect, n, "give one --meds tile");
  return names;
}

namespace {

// Every file a run reads: the inputs (each image path expanded per band, scene by scene), then the
// PSFEx models (one per band).
struct MetadetectFiles {
  io::CellSource::Images images;
  std::vector<std::string> files;
};

MetadetectFiles files_read(const MetadetectRunOptions& options, const std::vector<std::string>& bands) {
  MetadetectFiles out;
  if (options.tile) {
    out.files = options.inputs;
    return out;
  }
  const std::vector<std::string> names = bands.empty() ? std::vector<std::string>{""} : bands;
  for (const std::string& in : options.inputs) {
    out.images.names.push_back(in);
    out.images.files.emplace_back();
    for (const std::string& b : names) out.images.files.back().push_back(expand_band(in, b));
    out.files.insert(out.files.end(), out.images.files.back().begin(), out.images.files.back().end());
  }
  if (!options.psfex.empty())
    for (const std::string& b : names) out.images.psfex.push_back(expand_band(options.psfex, b));
  return out;
}

// check_metadetect_outputs, given the files the run reads.
void check_outputs_of(const MetadetectRunOptions& options, const MetadetectFiles& read,
                      const std::vector<std::string>& parts) {
  for (const std::string& in : read.files)
    if (io::same_file(in, options.output)) throw io::ConfigError("the output '" + options.output + "' is the input");
  for (const std::string& p : read.images.psfex)
    if (io::same_file(p, options.output)) throw io::ConfigError("the output '" + options.output + "' is --psfex");
  // Nor may an input be one of the files written beside the output, or a part (a failed run removes them).
  std::vector<io::RunOutput> outputs = {table_output("-o", options.output)};
  for (const std::string& part : parts) outputs.push_back(table_output("-o (a rank's part)", part));
  std::vector<io::RunInput> reads;
  for (const std::string& in : read.files) reads.push_back({"input", io::fits_root_name(in)});
  for (const std::string& p : read.images.psfex) reads.push_back({"--psfex", p});
  io::check_outputs(outputs, reads, true);
  if (!options.resume) io::refuse_to_replace(options.output, options.overwrite);
}

}  // namespace

void check_metadetect_outputs(const MetadetectRunOptions& options, const std::vector<std::string>& parts) {
  check_outputs_of(options, files_read(options, metadetect_bands(options)), parts);
}

std::vector<MetadetectRow> metadetect_image(const io::CellImage& image, const MetadetectOptions& options, int threads,
                                            long long* cells_failed) {
  std::string why;
  if (!options.IsValid(&why)) throw io::ConfigError(why);
  io::CellSource source(image, options);
  CollectingSink sink;
  set_detection_pixel_stack(static_cast<long long>(options.cell_size) * options.cell_size);
  PipelineOptions pipeline_options;
  pipeline_options.threads = threads;
  pipeline_options.batch_size = 2;
  run_pipeline(source, sink, [&] { return std::make_unique<CellBatchMeasurer>(options); }, pipeline_options);
  if (cells_failed) *cells_failed = sink.failed;
  return std::move(sink.rows);
}

MetadetectRunSummary run_metadetect(const MetadetectRunOptions& options,
                                    const std::function<void(const MetadetectProgress&)>& progress) {
  using Clock = std::chrono::steady_clock;
  const Clock::time_point start = Clock::now();
  std::string why;
  if (!options.metadetect.IsValid(&why)) throw io::ConfigError(why);
  if (options.inputs.empty()) throw io::ConfigError("no input image: give IMAGE.fits or --input-list");
  if (options.output.empty()) throw io::ConfigError("no output: give -o OUT.fits");
  if (options.cells_per_batch < 1) throw io::ConfigError("cells per batch must be >= 1");
  shard_range(0, options.shard, options.shards);  // checks the shard before anything is read
  const std::vector<std::string> bands = metadetect_bands(options);
  const MetadetectFiles read = files_read(options, bands);
  const io::CellSource::Images& images = read.images;
  const std::vector<std::string>& files = read.files;
  check_outputs_of(options, read, {});
  const io::OutputLock lock = io::OutputLock::acquire(options.output);

  io::CellSource source = options.tile ? io::CellSource(io::CellSource::Tile{options.inputs}, options.metadetect)
                                       : io::CellSource(images, options.metadetect);
  io::MetadetectWriterOptions writer_options;
  writer_options.path = options.output;
  writer_options.bands = bands;
  std::string fingerprint = "stampede " + std::string(program_version()) + " metadetect\n";
  writer_options.header.emplace_back("INPUTS", options.tile ? "cell tile" : "images");
  fingerprint += options.tile ? "cell tile\n" : "images\n";
  if (!bands.empty()) {
    std::string names;
    for (const std::string& b : bands) names += (names.empty() ? "" : ",") + b;
    writer_options.header.emplace_back("BANDS", names);
    fingerprint += "bands " + names + "\n";
  }
  for (const auto& [key, value] : metadetect_header_keys(options.metadetect)) {
    writer_options.header.emplace_back(key, value);
    fingerprint += key + "=" + value + "\n";
  }
  for (std::size_t i = 0; i < files.size(); ++i) {
    const io::FileDigest d = io::digest_file(files[i]);
    const std::string n = std::to_string(i + 1);
    writer_options.header.emplace_back("INPUT" + n, files[i]);
    writer_options.header.emplace_back("DIGEST" + n, d.text());
    fingerprint += "input " + files[i] + " " + d.text() + "\n";
  }
  for (std::size_t i = 0; i < images.psfex.size(); ++i) {
    const io::FileDigest d = io::digest_file(images.psfex[i]);
    const std::string n = std::to_string(i + 1);
    writer_options.header.emplace_back("PSFEX" + n, images.psfex[i]);
    writer_options.header.emplace_back("PSFEXD" + n, d.text());
    fingerprint += "psfex " + images.psfex[i] + " " + d.text() + "\n";
  }
  writer_options.header.emplace_back("NCELLS", std::to_string(source.total_objects()));
  const ShardRange range = shard_range(source.total_objects(), options.shard, options.shards);
  const long long begin = range.begin, end = range.end;
  // RUNFP identifies the measurement, not the shard: the shards' tables join into the whole run's.
  const std::string runfp = RunFingerprint().text(fingerprint).hex();
  writer_options.header.emplace_back(kRunFingerprintKey, runfp);
  if (options.shards > 1) {
    writer_options.header.emplace_back(kShardKey, shard_text(options.shard, options.shards));
    fingerprint += "shard " + shard_text(options.shard, options.shards) + "\n";
  }
  writer_options.header_types = metadetect_header_types();
  writer_options.header_types["NCELLS"] = io::HeaderValueType::kInteger;
  writer_options.fingerprint = fingerprint;

  MetadetectRunSummary summary;
  if (options.resume && is_this_runs_complete_table(options.output, "METADETECT", runfp)) {
    summary.skipped = true;
    return summary;
  }
  std::unique_ptr<io::MetadetectWriter> writer;
  if (options.resume) {
    writer = io::MetadetectWriter::resume(writer_options, &summary.cells_resumed, &summary.resume_started);
  } else {
    writer = io::MetadetectWriter::create(writer_options);
  }
  source.skip_to(begin + summary.cells_resumed);
  source.set_end(end);
  try {
    // SEP's pixel stack is global: sized for a whole cell above the threshold before threads start.
    set_detection_pixel_stack(source.max_cell_pixels());
    CellSink sink(*writer, source, &summary);
    PipelineOptions pipeline_options;
    pipeline_options.threads = options.threads;
    pipeline_options.batch_size = options.cells_per_batch;
    pipeline_options.stop = options.stop;
    const long long resumed = summary.cells_resumed;
    const PipelineSummary ran = run_pipeline(
        source, sink, [&] { return std::make_unique<CellBatchMeasurer>(options.metadetect); }, pipeline_options,
        [&](const PipelineProgress& p) {
          if (progress) progress({resumed + p.objects_done, end - begin, p.seconds});
        });
    summary.threads = ran.threads;
    summary.stopped = ran.stopped;
    if (!ran.stopped) writer->finish();
  } catch (...) {
    writer->abandon();
    throw;
  }
  summary.seconds = std::chrono::duration<double>(Clock::now() - start).count();
  return summary;
}

}  // namespace stampede::app
