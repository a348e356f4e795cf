// Fitting stamps that are already in memory (the Python module's arrays; later the MPI driver's
// scattered batches): the same pipeline, per-thread fitters and PSF preparation as a `stampede fit`
// run over a grid file, with the rows returned instead of written. Equal stamps, weights, PSF and
// options give rows bitwise equal to that run's, for any thread count.
#pragma once

#include <cstdint>
#include <memory>
#include <optional>
#include <span>
#include <vector>

#include "engine/model/psf_model.hpp"
#include "engine/pipeline/object_record.hpp"
#include "engine/pipeline/stamp_batch.hpp"
#include "app/run_config.hpp"

namespace stampede {
class StampFitter;
}

namespace stampede::app {

struct ArrayStamps {
  int count = 0;
  int stamp_size = 0;
  std::span<const double> pixels;   // count x stamp_size^2, row-major stamps one after another
  std::span<const double> weights;  // empty, or inverse variances in the pixels' layout
  // Empty: the configuration's PSF (psf_input and its keys); one: that PSF for every stamp;
  // count: one per stamp (a PSF that cannot be prepared flags its row kFlagPsfFailure).
  std::vector<PsfModel> psfs;
  // Rows are numbered as a grid read row by row: id = first_id + k, ix = k % grid_nx,
  // iy = k / grid_nx; 0 = one row of `count` stamps.
  int grid_nx = 0;
  std::int64_t first_id = 0;
};

// Fits every stamp on `threads` worker threads (0: the calling task arena's) and returns one row
// per stamp, in order. Throws io::ConfigError for options that do not validate (or a stamp_size set
// to other than the arrays'), std::invalid_argument for inconsistent arrays or an invalid PSF, and
// std::runtime_error when the shared PSF cannot be prepared. Bad pixels are flagged rows.
std::vector<ObjectRecord> fit_array_stamps(const app::RunConfig& config, const ArrayStamps& stamps, int threads);

// One stamp at a time on the calling thread, with the PSF prepared once: the Python module's
// Fitter, where one call per stamp must cost little beyond the fit. Not thread-safe (one per
// thread). Rows equal fit_array_stamps' for the same stamp, PSF and options.
class SingleStampFitter {
 public:
  // Validates as fit_array_stamps (psf empty: the configuration's PSF; moffat_catalog refused).
  SingleStampFitter(const app::RunConfig& config, int stamp_size, std::optional<PsfModel> psf);
  ~SingleStampFitter();
  int stamp_size() const { return stamp_size_; }
  // pixels (and weights, if not empty) hold stamp_size^2 values; throws std::invalid_argument if not.
  ObjectRecord fit(std::span<const double> pixels, std::span<const double> weights, std::int64_t id = 0);

 private:
  int stamp_size_;
  std::unique_ptr<StampFitter> fitter_;
  StampBatch batch_;
};

}  // namespace stampede::app
