// The batch pipeline; see pipeline.hpp.
#include "engine/pipeline.hpp"

#include <tbb/concurrent_queue.h>
#include <tbb/enumerable_thread_specific.h>
#include <tbb/global_control.h>
#include <tbb/info.h>
#include <tbb/parallel_pipeline.h>

#include <atomic>
#include <exception>
#include <mutex>
#include <thread>
#include <vector>

namespace stampede {

PipelineSummary run_pipeline(StampSource& source, BatchSink& sink,
                             const std::function<std::unique_ptr<BatchFitter>()>& make_fitter,
                             const PipelineOptions& options,
                             const std::function<void(const PipelineProgress&)>& progress) {
  const int threads = options.threads > 0 ? options.threads : tbb::info::default_concurrency();
  tbb::global_control limit(tbb::global_control::max_allowed_parallelism, threads);
  const int pool_size = std::max(2, options.batches_per_thread * threads);
  std::vector<std::unique_ptr<StampBatch>> pool;
  tbb::concurrent_bounded_queue<StampBatch*> free_batches;
  for (int i = 0; i < pool_size; ++i) {
    pool.push_back(std::make_unique<StampBatch>(options.batch_size, options.stamp_size, options.per_object_psf));
    free_batches.push(pool.back().get());
  }
  tbb::concurrent_queue<StampBatch*> finished;  // fit tasks -> writer
  std::atomic<long long> finished_signal{0};
  std::atomic<bool> reader_done{false}, cancelled{false};
  std::atomic<long long> batches_read{0};
  std::exception_ptr writer_error;
  PipelineSummary summary;
  const auto t0 = std::chrono::steady_clock::now();
  const long long total = source.total_objects();

  // Writer thread: the only consumer of `finished`; writes batches in sequence order.
  std::thread writer([&] {
    std::vector<StampBatch*> reorder(pool_size, nullptr);  // slot = sequence % pool_size
    long long next = 0;
    PipelineProgress p;
    p.objects_total = total;
    while (true) {
      const long long seen = finished_signal.load(std::memory_order_acquire);
      StampBatch* b = nullptr;
      while (finished.try_pop(b)) reorder[b->sequence % pool_size] = b;
      while (StampBatch* ready = reorder[next % pool_size]) {
        if (ready->sequence != next) break;
        reorder[next % pool_size] = nullptr;
        if (!cancelled.load()) {
          try {
            sink.write(*ready);
          } catch (...) {
            writer_error = std::current_exception();
            cancelled.store(true);
          }
        }
        p.objects_done += ready->count;
        ++next;
        free_batches.push(ready);
        if (progress && !cancelled.load()) {
          p.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
          progress(p);
        }
      }
      if (reader_done.load(std::memory_order_acquire) && (next == batches_read.load() || cancelled.load())) break;
      finished_signal.wait(seen, std::memory_order_acquire);  // sleep until a batch arrives
    }
    summary.objects = p.objects_done;
    summary.batches = next;
  });

  tbb::enumerable_thread_specific<std::unique_ptr<BatchFitter>> fitters;
  std::exception_ptr pipeline_error;
  long long sequence = 0;
  try {
    tbb::parallel_pipeline(
        static_cast<std::size_t>(pool_size),
        tbb::make_filter<void, StampBatch*>(tbb::filter_mode::serial_in_order,
                                            [&](tbb::flow_control& fc) -> StampBatch* {
                                              if (cancelled.load()) {
                                                fc.stop();
                                                return nullptr;
                                              }
                                              StampBatch* b = nullptr;
                                              free_batches.pop(b);  // blocks while all batches are in flight
                                              b->sequence = sequence;
                                              if (!source.fill(*b) || b->count == 0) {
                                                free_batches.push(b);
                                                fc.stop();
                                                return nullptr;
                                              }
                                              ++sequence;
                                              batches_read.fetch_add(1);
                                              return b;
                                            }) &
            tbb::make_filter<StampBatch*, StampBatch*>(tbb::filter_mode::parallel,
                                                       [&](StampBatch* b) {
                                                         auto& f = fitters.local();
                                                         if (!f) f = make_fitter();
                                                         if (!cancelled.load()) f->fit(*b);
                                                         return b;
                                                       }) &
            tbb::make_filter<StampBatch*, void>(tbb::filter_mode::serial_out_of_order, [&](StampBatch* b) {
              finished.push(b);
              finished_signal.fetch_add(1, std::memory_order_release);
              finished_signal.notify_one();
            }));
  } catch (...) {
    pipeline_error = std::current_exception();
    cancelled.store(true);
  }
  reader_done.store(true, std::memory_order_release);
  finished_signal.fetch_add(1, std::memory_order_release);
  finished_signal.notify_one();
  writer.join();
  if (pipeline_error) std::rethrow_exception(pipeline_error);
  if (writer_error) std::rethrow_exception(writer_error);
  summary.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return summary;
}

}  // namespace stampede
