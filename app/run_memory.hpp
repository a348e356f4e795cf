// The resident memory a fit run will need, estimated before it starts so that a thread count the
// machine cannot hold is refused up front rather than swapping or being killed mid-run.
#pragma once

#include <string>

#include "app/run_config.hpp"

namespace stampede::app {

struct RunMemoryEstimate {
  int threads = 0;
  double batch_bytes = 0;       // one batch: pixels, weights, records (and PSFs) of batch_size stamps
  int batches = 0;              // the pipeline's pool: 3 per thread, at least 2
  double per_thread_bytes = 0;  // a worker's fitter and renderer work space
  double total_bytes() const { return batches * batch_bytes + threads * per_thread_bytes; }
};

// For `threads` workers (> 0) with the configuration's batch_size, stamp_size and model grid.
RunMemoryEstimate estimate_fit_memory(const app::RunConfig& config, int threads);

// Throws ConfigError naming the thread count when the estimate exceeds `available_bytes`.
void check_fit_memory(const RunMemoryEstimate& estimate, double available_bytes);

}  // namespace stampede::app
