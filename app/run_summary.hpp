// What a fit run did, in the manner of Ceres' Solver::Summary: counts per fit status, objects,
// wall time per phase, the rate, and the run's paths; BriefReport() is the one line `stampede fit`
// prints at the end, FullReport() a multi-line account.
#pragma once

#include <array>
#include <string>

#include "engine/fit/fit_result.hpp"

namespace stampede::app {

struct RunSummary {
  // Objects fitted by this run, per FitStatus value (resumed objects are not counted again).
  std::array<long long, kFitStatusCount> by_status{};
  long long objects = 0;  // fitted by this run
  long long resumed = 0;  // committed by the interrupted run this one continued
  bool interrupted = false;  // stopped by FitRunOptions::stop: the output is partial, resumable
  bool skipped = false;   // resume found the output complete, this run's table (its RUNFP)
  long long batches = 0;
  int threads = 0;        // worker threads the pipeline ran with

  // Wall time, measured per phase, seconds.
  double setup_seconds = 0;     // input, configuration, PSF and writer, up to the first batch
  double pipeline_seconds = 0;  // reading, fitting and writing every batch (run_pipeline)
  double finish_seconds = 0;    // closing and renaming the outputs, saving FFTW wisdom
  double total_seconds = 0;     // the whole run

  std::string input, catalog, weight, output, text_output;  // "" where the run had none

  long long count(FitStatus s) const { return by_status[static_cast<int>(s)]; }
  // Objects fitted per second of the pipeline phase.
  double objects_per_second() const;

  // "stampede fit: N objects (R resumed) in T s, X objects/s; status: ok=N ...; wrote OUT" (the
  // statuses that occurred, in enum order; "; wrote OUT" only with an output), no newline.
  std::string BriefReport() const;
  // "ok=N psf_failure=M ..." for the statuses that occurred, in enum order.
  std::string StatusCounts() const;
  // Every status with its count, the phases, the rate and the paths; lines end in '\n'.
  std::string FullReport() const;
};

}  // namespace stampede::app
