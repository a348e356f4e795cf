// The throughput engine: a thin serial reader, parallel fit tasks, a thin serial writer.
//
//   reader (serial, in order) -> fit (parallel) -> hand-off (serial, any order)
//     -> lock-free MPSC stack -> writer thread (reorder buffer) -> sink, batch back to the pool
//
// oneTBB's parallel_pipeline runs the first three stages with at most `pool size` batches in flight;
// the writer is a dedicated thread so a slow disk never blocks a fit task, and it restores input
// order with a reorder buffer that the pool bounds. Memory is the pool (batch_size x tokens
// stamps), whatever the catalogue size. Each worker thread owns its fitting state (`BatchFitter`);
// results do not depend on which thread fitted what.
#pragma once

#include <atomic>
#include <chrono>
#include <functional>
#include <memory>

#include "engine/pipeline/stamp_batch.hpp"

namespace stampede {

// Per-thread fitting state (FFTW plans, fitter, scratch). Created lazily on each worker thread.
class BatchFitter {
 public:
  virtual ~BatchFitter() = default;
  virtual void fit(StampBatch& batch) = 0;
};

struct PipelineOptions {
  int threads = 0;          // fit threads, in a task arena of the run's own; 0: the caller's arena's (all cores)
  int batch_size = 32;      // stamps per batch
  int batches_per_thread = 3;
  // Set from another thread to end the run early: no batch is read after it is seen, those in
  // flight are fitted and written (PipelineSummary::stopped).
  const std::atomic<bool>* stop = nullptr;
};

struct PipelineProgress {
  long long objects_done = 0;
  long long objects_total = -1;
  double seconds = 0;
};

struct PipelineSummary {
  long long objects = 0;
  long long batches = 0;
  int threads = 0;  // the arena's concurrency
  double seconds = 0;
  bool stopped = false;  // ended by PipelineOptions::stop before the source was exhausted
};

PipelineSummary run_pipeline(StampSource& source, BatchSink& sink,
                             const std::function<std::unique_ptr<BatchFitter>()>& make_fitter,
                             const PipelineOptions& options,
                             const std::function<void(const PipelineProgress&)>& progress = {});

}  // namespace stampede
