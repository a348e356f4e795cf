// The noise-bias calibration build (`stampede calibrate build`): simulates the calibration grid
// with the run's PSF, fits it with the run's configuration through the pipeline, measures each
// point's bias, fits the bias curves and writes the calibration table. Progress is kept point by
// point in OUTPUT.partial (fsync'd), so an interrupted build resumes after its last completed
// point. Prints nothing: the caller gets the plan, progress through a callback, and a summary.
#pragma once

#include <functional>
#include <memory>
#include <string>

#include "app/psf_setup.hpp"
#include "engine/calibration/calibration_grid.hpp"
#include "engine/calibration/noise_bias.hpp"
#include "io/output_lock.hpp"
#include "app/run_config.hpp"

namespace stampede::app {

struct CalibrationBuildOptions {
  // The grid (snr, radii, bulge_fractions, e_max, e_steps, realisations, seed); its noise_sigma,
  // stamp_size, bulge_radius_ratio and PSF are the configuration's.
  CalibrationGridOptions grid;
  app::RunConfig config;   // the science run's: psf_input moffat or airy, noise_sigma > 0
  std::string output;     // the calibration table; progress in OUTPUT.partial
  int threads = 0;        // 0: all of the calling task arena's
  bool resume = false;    // continue from OUTPUT.partial
  bool overwrite = false; // replace an existing OUTPUT
};

struct CalibrationBuildProgress {
  long long fits_done = 0, fits_total = 0;  // including the points of a resumed build
  long long point = 0;                      // grid points completed
  int points = 0;
  double seconds = 0;                       // since the fitting began
  double fits_per_second = 0, eta_seconds = 0;
  // "D/T fits (P%), point K/N, R fits/s, ETA E s   ".
  std::string Line() const;
};

struct CalibrationBuildSummary {
  CalibrationTable table;  // as written to the output
  std::string output;
  bool fitted = false;     // false: every point came from the resumed progress file
  long long fits = 0;      // fitted by this build
  double fit_seconds = 0;
  // "stampede calibrate build: N fits in T s, R fits/s" (only meaningful when fitted).
  std::string BriefReport() const;
  // The noise pairs used and lost, the mean error of a point's bias, m and c at e = 0 per (r_d, F),
  // and "wrote OUTPUT"; lines end in '\n'.
  std::string FullReport() const;
};

class BuildCheckpoint;

class CalibrationBuild {
 public:
  // Validates the options and configuration, builds the PSF and the grid, and opens (or with
  // resume, reads) the progress file. Throws io::ConfigError for a configuration the build cannot
  // use, io::FileError for an output it must not write (io/output_check.hpp), std::runtime_error
  // for the progress file.
  explicit CalibrationBuild(CalibrationBuildOptions options);
  ~CalibrationBuild();

  int points() const;
  int first_point() const;  // > 0 when a resumed build continues
  // "stampede calibrate build: N grid points (...) x R noise pairs = F fits at S/N X[, resuming at point K]".
  std::string PlanReport() const;

  // Fits the points not yet measured, then writes the table (OUTPUT.tmp renamed) and removes the
  // progress file. `progress` is called from the pipeline's writer thread, at most every 0.5 s.
  CalibrationBuildSummary run(const std::function<void(const CalibrationBuildProgress&)>& progress = {});

 private:
  CalibrationBuildOptions options_;
  io::OutputLock lock_;  // held for the build's life: a second build on the output is refused
  app::SharedPsf psf_;
  std::unique_ptr<CalibrationGrid> grid_;
  std::unique_ptr<BuildCheckpoint> checkpoint_;
};

}  // namespace stampede::app
