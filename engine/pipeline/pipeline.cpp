// The batch pipeline; see pipeline.hpp.
#include "engine/pipeline/pipeline.hpp"

#include "engine/pipeline/mpsc_stack.hpp"
#include "engine/pipeline/tsan_annotations.hpp"

#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_pipeline.h>
#include <tbb/task_arena.h>

#include <atomic>
#include <condition_variable>
#include <exception>
#include <mutex>
#include <thread>
#include <vector>

namespace stampede {

namespace {

// The pool of free batches: the reader takes one (blocking while all are in flight), the writer
// gives it back once written. Its size bounds memory and the batches in flight.
class BatchPool {
 public:
  void put(StampBatch* b) {
    {
      std::lock_guard<std::mutex> lock(mutex_);
      free_.push_back(b);
    }
    ready_.notify_one();
  }
  StampBatch* take() {
    std::unique_lock<std::mutex> lock(mutex_);
    ready_.wait(lock, [&] { return !free_.empty(); });
    StampBatch* b = free_.back();
    free_.pop_back();
    return b;
  }
  void reserve(std::size_t n) { free_.reserve(n); }

 private:
  std::mutex mutex_;
  std::condition_variable ready_;
  std::vector<StampBatch*> free_;
};

}  // namespace

PipelineSummary run_pipeline(StampSource& source, BatchSink& sink,
                             const std::function<std::unique_ptr<BatchFitter>()>& make_fitter,
                             const PipelineOptions& options,
                             const std::function<void(const PipelineProgress&)>& progress) {
  // The run's threads are a task arena of its own, made here because the token pool is sized from
  // the same count: the caller's other oneTBB work (a Python or MPI host, a second run) is not
  // limited or changed, as a process-wide tbb::global_control would. 0 takes the concurrency of the
  // arena the caller runs in (all cores, outside any).
  const int threads = options.threads > 0 ? options.threads : tbb::this_task_arena::max_concurrency();
  tbb::task_arena arena(threads);
  const int pool_size = std::max(2, options.batches_per_thread * threads);
  std::vector<std::unique_ptr<StampBatch>> batches;
  BatchPool pool;
  pool.reserve(pool_size);
  for (int i = 0; i < pool_size; ++i) {
    batches.push_back(std::make_unique<StampBatch>(options.batch_size));
    pool.put(batches.back().get());
  }
  MpscStack<StampBatch> finished;  // fit tasks -> writer, lock-free
  std::atomic<bool> reader_done{false}, cancelled{false};
  bool stopped = false;  // the reader stage's (serial); read after the pipeline has joined
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
      const unsigned long long seen = finished.signal();
      for (StampBatch* b = finished.take_all(); b;) {
        StampBatch* following = b->next;
        reorder[b->sequence % pool_size] = b;
        b = following;
      }
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
        pool.put(ready);
        if (progress && !cancelled.load()) {
          p.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
          progress(p);
        }
      }
      if (reader_done.load(std::memory_order_acquire) && (next == batches_read.load() || cancelled.load())) break;
      finished.wait(seen);  // sleep until a batch arrives
    }
    summary.objects = p.objects_done;
    summary.batches = next;
  });

  tbb::enumerable_thread_specific<std::unique_ptr<BatchFitter>> fitters;
  std::exception_ptr pipeline_error;
  long long sequence = 0;
  // TSan tokens (tsan_annotations.hpp): start of the run, the serial reader's and hand-off's turns,
  // and the end of every fit (for the main thread that destroys the per-thread fitters).
  int start_token = 0, reader_token = 0, handoff_token = 0, fit_token = 0;
  try {
    const auto filters =
        tbb::make_filter<void, StampBatch*>(tbb::filter_mode::serial_in_order,
                                            [&](tbb::flow_control& fc) -> StampBatch* {
                                              STAMPEDE_TSAN_ACQUIRE(&start_token);
                                              STAMPEDE_TSAN_ACQUIRE(&reader_token);
                                              struct TurnEnd {
                                                int* token;
                                                ~TurnEnd() { STAMPEDE_TSAN_RELEASE(token); }
                                              } turn_end{&reader_token};
                                              if (cancelled.load()) {
                                                fc.stop();
                                                return nullptr;
                                              }
                                              if (options.stop && options.stop->load()) {
                                                stopped = true;
                                                fc.stop();
                                                return nullptr;
                                              }
                                              StampBatch* b = pool.take();  // blocks while all are in flight
                                              b->sequence = sequence;
                                              if (!source.fill(*b) || b->count == 0) {
                                                pool.put(b);
                                                fc.stop();
                                                return nullptr;
                                              }
                                              ++sequence;
                                              batches_read.fetch_add(1);
                                              STAMPEDE_TSAN_RELEASE(b);
                                              return b;
                                            }) &
            tbb::make_filter<StampBatch*, StampBatch*>(tbb::filter_mode::parallel,
                                                       [&](StampBatch* b) {
                                                         STAMPEDE_TSAN_ACQUIRE(&start_token);
                                                         STAMPEDE_TSAN_ACQUIRE(b);
                                                         auto& f = fitters.local();
                                                         if (!f) f = make_fitter();
                                                         if (!cancelled.load()) f->fit(*b);
                                                         STAMPEDE_TSAN_RELEASE(b);
                                                         STAMPEDE_TSAN_RELEASE(&fit_token);
                                                         return b;
                                                       }) &
            tbb::make_filter<StampBatch*, void>(tbb::filter_mode::serial_out_of_order,
                                                [&](StampBatch* b) {
                                                  STAMPEDE_TSAN_ACQUIRE(&handoff_token);
                                                  STAMPEDE_TSAN_ACQUIRE(b);
                                                  finished.push(b);
                                                  STAMPEDE_TSAN_RELEASE(&handoff_token);
                                                });
    STAMPEDE_TSAN_RELEASE(&start_token);  // after the filters exist: workers read them
    arena.execute([&] { tbb::parallel_pipeline(static_cast<std::size_t>(pool_size), filters); });
  } catch (...) {
    pipeline_error = std::current_exception();
    cancelled.store(true);
  }
  STAMPEDE_TSAN_ACQUIRE(&fit_token);
  STAMPEDE_TSAN_ACQUIRE(&reader_token);
  reader_done.store(true, std::memory_order_release);
  finished.poke();
  writer.join();
  if (pipeline_error) std::rethrow_exception(pipeline_error);
  if (writer_error) std::rethrow_exception(writer_error);
  summary.threads = threads;
  summary.stopped = stopped;
  summary.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return summary;
}

}  // namespace stampede
