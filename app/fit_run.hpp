// A fit run: the composition of `stampede fit` for any front end (the command line, the Python
// module, the MPI driver) over the run harness (app/run_harness): its input (app/fit_input: a
// stamp grid, an image with a catalogue, or MEDS tiles, with the PSF set up), the fit catalogue's
// schema (io/catalog_writer) and the sink that writes it (app/fit_table_sink), the pipeline with
// the requested threads, and a RunSummary. It prints nothing and never exits: progress and
// warnings go to the callbacks the caller gives; a systemic failure throws the error types of io/
// (ConfigError, FitsError, CatalogError, FileError) or std::runtime_error.
//
// The harness checks and locks the outputs before anything is read, resumes, skips this run's
// complete table, and keeps the committed rows of a run whose write ran out of room; a run that
// fails otherwise removes its partial outputs; a killed one leaves them for resume, whose
// fingerprint covers the inputs' contents (app/run_fingerprint.hpp).
#pragma once

#include <atomic>
#include <functional>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <utility>

#include "app/run_harness.hpp"
#include "app/run_summary.hpp"
#include "engine/pipeline/object_record.hpp"
#include "engine/pipeline/pipeline.hpp"
#include "app/run_config.hpp"

namespace stampede::app {

// The per-thread fitter of a survey run's batches with this configuration (the run's own and an
// MPI worker's). Throws io::ConfigError for options that cannot work together.
std::unique_ptr<BatchFitter> make_survey_fitter(const app::RunConfig& config, const std::vector<std::string>& meds,
                                                const std::vector<std::string>& bands);

struct FitRunOptions {
  std::string input;        // a grid of stamps, or with `catalog` the image to cut them from
  // MEDS tiles (`--meds`), instead of `input`: each object fitted jointly on its cutouts
  // (io/meds_object_source, app/survey_object_fit; options meds_*), one survey row per object (io/result_columns). Several
  // tiles are one per band of the same objects, fitted jointly.
  std::vector<std::string> meds;
  // The bands of `meds`, in its order (`--bands g,r,i`); empty: none for one tile, b0, b1, ... for
  // several. Given, the table has each band's columns (flux_<band>, ...), one band included.
  std::vector<std::string> bands;
  std::string catalog;      // FITS table or text 'id x y' of objects in `input`; "" = grid input
  std::string weight;       // inverse-variance image of input's shape; "" = config's noise_sigma
  std::string output;       // FITS table; "" = none: rows only go to on_rows (no resume, no save_images)
  std::string text_output;  // the table also as whitespace text; "" = none
  bool resume = false;      // continue the interrupted run at `output` (same input and options)
  // With resume, an output that is already complete (no checkpoint) is this run's when its RUNFP
  // matches: the run is skipped (RunSummary::skipped); another run's is refused.
  bool overwrite = false;   // replace existing outputs (table, text, images); else they are refused
  int threads = 0;          // worker threads; 0 = all of the calling task arena's (all cores by default)
  // Job-array shard `shard` of `shards` (`--shard i/N`): the contiguous objects
  // [total*i/N, total*(i+1)/N) of the input, with their whole-input ids; the table records SHARD
  // "i/N" and SHARDTOT (the input's objects) for app/shard_merge, and the whole run's RUNFP. 0 of
  // 1: the whole input.
  int shard = 0;
  int shards = 1;
  bool quiet = false;       // no end-of-run warnings (FFTW wisdom not saved); input warnings still go out
  app::RunConfig config;     // validated by run(); stamp_size from the grid's STAMPSZ unless set

  // Called from the pipeline's writer thread, at most every progress_interval seconds.
  std::function<void(const RunProgress&)> on_progress;
  double progress_interval = 0.5;
  // A problem that does not stop the run (e.g. the input records another PSF); the text has no prefix.
  std::function<void(const std::string&)> on_warning;
  // Every batch's rows, in input order, from the writer thread, after they are written.
  std::function<void(std::span<const ObjectRecord>)> on_rows;
  // Set from another thread to stop the run (the Python module's Ctrl-C): no batch is read after it
  // is seen, those in flight are written, and run() returns with RunSummary::interrupted, the
  // outputs left as a killed run leaves them (partials and checkpoint, for resume).
  const std::atomic<bool>* stop = nullptr;
  // Empty: every fit in this process (threads). Set: the fits go where it says (app/run_harness).
  Distributor distribute;
};

class FitRun {
 public:
  explicit FitRun(FitRunOptions options) : options_(std::move(options)) {}
  // Fits every object (after the committed ones, with resume). Each call is a complete run with its
  // own PSF, writer and threads; nothing outlives it but the outputs.
  RunSummary run() const;

 private:
  FitRunOptions options_;
};

}  // namespace stampede::app
