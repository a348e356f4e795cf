// The run harness: what every run that writes a table does, fit and metadetect and their MPI modes
// alike, in this order —
//   1. protect_outputs: the outputs checked against every file the run reads (no output is an
//      input, a list, a model, or a file written beside another output) and locked, before
//      anything is read or any rank or thread starts;
//   2. seal_identity: the run's identity in its table (RUNFP, the hash of its fingerprint: inputs'
//      contents, options, program version) and its shard's keys;
//   3. open_table: this run's complete table skipped, an interrupted one resumed (or started afresh
//      when nothing was committed), else the table created;
//   4. measure_table: the shard's units after the committed ones through the pipeline (a per-thread
//      measurer, the composition's sink writing the schema's rows), with stop and progress; the
//      table finished, or abandoned on an error (its committed rows kept when a write ran out of
//      room).
// A composition (app/fit_run, app/metadetect_run) brings its io source, its measurer and its
// table's schema (an io::TableWriter) and its header keys; the rest is here.
#pragma once

#include <atomic>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "engine/pipeline/pipeline.hpp"
#include "io/config_error.hpp"
#include "io/output_check.hpp"
#include "io/output_lock.hpp"
#include "io/table_writer.hpp"

namespace stampede::app {

// The header keys of a shard's table: "i/N", and (fit) the whole input's object count.
inline constexpr const char* kShardKey = "SHARD";
inline constexpr const char* kShardTotalKey = "SHARDTOT";
// The run's identity in its table's header: RUNFP, 16 hex digits of the hash of its fingerprint
// (inputs' contents, options, program version; not the shard: a run's shards share it), which a
// resume of a complete table compares.
inline constexpr const char* kRunFingerprintKey = "RUNFP";

// Worker threads, one rule for every front end (CLI --threads, Python threads=, MPI): 0 = all of
// the machine's cores, else 1 .. kMaxThreads. Throws io::ConfigError naming `what` otherwise.
inline constexpr int kMaxThreads = 4096;
void check_threads(long long threads, const std::string& what);

// "I/N" (the --shard argument and the SHARD key) as {I, N}; nullopt unless it is exactly two
// integers with 0 <= I < N <= 1000000.
std::optional<std::pair<int, int>> parse_shard(const std::string& text);
// Shard `shard` of `shards` of `total` units (objects, cells): [begin, end), the shards' sizes
// differing by at most one. Throws io::ConfigError unless 0 <= shard < shards.
struct ShardRange {
  long long begin = 0, end = 0;
};
ShardRange shard_range(long long total, int shard, int shards);
// "I/N".
std::string shard_text(int shard, int shards);

// A table output named by `option` (-o) with the files written beside it while the run is in
// progress: PATH.partial, PATH.checkpoint (and its temporary), PATH.lock.
io::RunOutput table_output(const std::string& option, const std::string& path);

// Refuses (io::CatalogError naming it) a table that a run has not finished, where `role` (a shard,
// a metrics input) needs a finished one: a run's temporary (NAME.partial, .checkpoint, its .tmp,
// .lock) or a table with a checkpoint beside it (a run is replacing it, or was stopped doing so).
void refuse_unfinished_table(const std::string& path, const std::string& role);

// For a resume: true when `path` is a complete table (no checkpoint) whose HDU `extname` records
// `runfp` as kRunFingerprintKey: the run is done and is skipped. False when there is no complete
// table there. Throws io::ConfigError naming it when it is another run's, with the first of this
// run's `header` keys whose value differs there (or not a table).
bool is_this_runs_complete_table(const std::string& path, const std::string& extname, const std::string& runfp,
                                 const std::vector<std::pair<std::string, std::string>>& header = {});

// A run's progress: units done (the resumed ones included) of the run's (its shard's).
struct RunProgress {
  long long done = 0, total = 0;
  double seconds = 0;         // since the pipeline started
  double per_second = 0;      // measured by this run
  double eta_seconds = 0;
  const char* unit = "object";
  // "D/T UNITs (P%), R UNITs/s, ETA E s   " (padded so that a shorter line overwrites it).
  std::string Line() const;
};

// How a run spreads its measurements beyond this process (the MPI driver's ranks). The composition
// describes its measurer for a worker elsewhere (WorkerRecipe: its kind and key = value lines, from
// which app/worker_recipe's worker_measurers makes the same measurer); the distributor returns the
// factory the pipeline uses instead of `local` (each measurement here or on a worker), the
// pipeline's thread count (measurements in flight) and what ends the workers' part of the run.
// Called once per run, before its first batch. A batch carries everything its measurement needs (a
// grid's stamps, a survey object's cutouts and PSFs). Only the fit distributes today: a
// metadetection's ranks read and measure shards of their own (docs/run_harness.md, "MPI").
struct WorkerRecipe {
  std::string kind;  // "fit"
  std::vector<std::pair<std::string, std::string>> lines;
  int batch_size = 1;
};
using MeasurerFactory = std::function<std::unique_ptr<BatchFitter>()>;
struct Distribution {
  MeasurerFactory make_measurer;
  int pipeline_threads = 0;
  std::function<void()> finish;  // after the pipeline, whether it ended, stopped or failed
};
using Distributor = std::function<Distribution(const WorkerRecipe& recipe, MeasurerFactory local)>;

// What a table-writing run asks of the harness, in its front end's words.
struct TableRun {
  std::string output;
  std::string extname;        // the table's HDU ("RESULTS", "METADETECT")
  const char* unit = "object";  // what it measures one by one ("cell"), in messages
  bool resume = false;
  bool overwrite = false;
  int shard = 0, shards = 1;  // --shard i/N
  const std::atomic<bool>* stop = nullptr;  // set from another thread: no batch is read after it
  std::function<void(const RunProgress&)> on_progress;  // at most every progress_interval seconds
  double progress_interval = 0.5;
  std::function<void(const std::string&)> on_warning;
  Distributor distribute;  // empty: every measurement in this process
  void warn(const std::string& text) const {
    if (on_warning) on_warning(text);
  }
};

// The harness's request from a run's options (FitRunOptions, MetadetectRunOptions: each holds these
// fields under these names; `distribute` where the run has it).
template <class RunOptions>
TableRun table_run(const RunOptions& options, std::string extname, const char* unit) {
  TableRun table;
  table.output = options.output;
  table.extname = std::move(extname);
  table.unit = unit;
  table.resume = options.resume;
  table.overwrite = options.overwrite;
  table.shard = options.shard, table.shards = options.shards;
  table.stop = options.stop;
  table.on_progress = options.on_progress;
  table.progress_interval = options.progress_interval;
  table.on_warning = options.on_warning;
  if constexpr (requires { options.distribute; }) table.distribute = options.distribute;
  return table;
}

// 1. Throws io::FileError naming the option and the files (io/output_check.hpp); locks each output
// whose companions name its lock (io::OutputLock::path_for) until the locks are released.
std::vector<io::OutputLock> protect_outputs(const TableRun& run, const std::vector<io::RunOutput>& outputs,
                                            const std::vector<io::RunInput>& inputs);

// 2. Appends RUNFP (the hash of table->fingerprint) to the header, then for a shard its key SHARD
// (and with `total_key`, the whole run's `units` under it) and "shard i/N of T" to the fingerprint:
// the shards of one run share RUNFP (their tables join into the whole run's), and a shard resumes
// only as that shard. Throws io::ConfigError for a shard of an input whose count is unknown (< 0).
void seal_identity(const TableRun& run, long long units, io::TableWriterOptions* table, const char* total_key = nullptr);

// The RUNFP that seal_identity recorded in `table`'s header.
std::string recorded_runfp(const io::TableWriterOptions& table);

// 3. The table of a schema (Writer::create, Writer::resume), or null when the run's output is this
// run's complete table (its RUNFP, as seal_identity recorded it): the run is done.
template <class Writer, class Options>
std::unique_ptr<Writer> open_table(const TableRun& run, const Options& options) {
  if (run.resume && is_this_runs_complete_table(run.output, run.extname, recorded_runfp(options), options.header))
    return nullptr;
  if (!run.resume) return Writer::create(options);
  std::unique_ptr<Writer> writer = Writer::resume(options);
  if (writer->started_afresh())
    run.warn("nothing to resume at " + run.output + ": no " + run.unit + " was committed; the run starts from the first");
  return writer;
}

// 4. The shard of `whole` (null for the whole run), moved past its `committed` units.
std::unique_ptr<StampSource> shard_source(const TableRun& run, StampSource& whole, long long committed);
// Runs the pipeline over `source` (its units after `committed`), `sink` writing `table` (null:
// none), each batch measured here by `make_measurer`'s measurers or, with run.distribute, where it
// sends them (`recipe` tells the workers the measurer); finishes the table unless stopped;
// abandons it on an error, and rethrows.
PipelineSummary measure_table(const TableRun& run, StampSource& source, long long committed, BatchSink& sink,
                              io::TableWriter* table, const MeasurerFactory& make_measurer, PipelineOptions pipeline,
                              const WorkerRecipe& recipe = {});

}  // namespace stampede::app
