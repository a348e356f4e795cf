// The fit run's memory estimate; see run_memory.hpp.
#include "app/run_memory.hpp"

#include <algorithm>
#include <cstdio>

#include "engine/pipeline/object_record.hpp"
#include "engine/pipeline/observation_arena.hpp"
#include "engine/pipeline/pipeline.hpp"
#include "engine/render/render_options.hpp"

namespace stampede::app {

RunMemoryEstimate estimate_fit_memory(const app::RunConfig& config, int threads) {
  RunMemoryEstimate e;
  e.threads = threads;
  const double npix = static_cast<double>(config.fitter.render.stamp_size) * config.fitter.render.stamp_size;
  // A stamp in the batch: its pixels and weights, its observation and reading entries, its row.
  const double per_stamp = 2 * npix * sizeof(double) + sizeof(ArenaObservation) + sizeof(BandReading) +
                           sizeof(std::string) + sizeof(ObjectRecord);
  e.batch_bytes = config.batch_size * per_stamp;
  e.batches = std::max(2, PipelineOptions{}.batches_per_thread * threads);
  // The upsampled renderer keeps 7 model-grid images (two components, five shape derivatives) and
  // the FFT's real and complex buffers, about 10 grids; the fitter and the stamp-sized images of
  // the renderer about 32 stamps; plans and scratch about 1 MiB.
  const double grid = GridGeometry(config.fitter.render).size;
  e.per_thread_bytes = 10 * grid * grid * sizeof(double) + 32 * npix * sizeof(double) + 1024.0 * 1024.0;
  return e;
}

void check_fit_memory(const RunMemoryEstimate& e, double available_bytes) {
  if (e.total_bytes() <= available_bytes) return;
  char msg[400];
  std::snprintf(msg, sizeof msg,
                "threads = %d: the run would need about %.3g GB (%d batches of %.3g MB, batch_size stamps each, "
                "and %.3g MB of work space per thread), more than the %.3g GB this machine has available "
                "(MemAvailable); use fewer threads or a smaller batch_size",
                e.threads, e.total_bytes() / 1e9, e.batches, e.batch_bytes / 1e6, e.per_thread_bytes / 1e6,
                available_bytes / 1e9);
  throw io::ConfigError(msg);
}

}  // namespace stampede::app
