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

// Under TSan: the main thread releases this token once a run's state and filters exist; every filter
// call acquires it before it reads that state. It is a global so that the acquire reads no memory.
int run_start_token = 0;

// A filter's captured pointer, read from its closure. The closure is oneTBB's copy of our filter,
// made by the main thread inside parallel_pipeline and ordered before this call by libtbb, which
// is not built for TSan and whose ordering TSan cannot see: that one read is exempt. What the pointer
// leads to was written before run_start_token's release, which is acquired here.
template <class T>
T& captured(T* const& pointer) {
  STAMPEDE_TSAN_IGNORE_READS_BEGIN();
  T* p = pointer;
  STAMPEDE_TSAN_IGNORE_READS_END();
  STAMPEDE_TSAN_ACQUIRE(&run_start_token);
  return *p;
}

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
  // What the filters use, reached through one captured pointer (see captured()), with the TSan
  // tokens of the serial reader's and hand-off's turns and of the end of every fit (for the main
  // thread that destroys the per-thread fitters).
  struct Stages {
    std::atomic<bool>& cancelled;
    const PipelineOptions& options;
    bool& stopped;
    BatchPool& pool;
    StampSource& source;
    std::atomic<long long>& batches_read;
    tbb::enumerable_thread_specific<std::unique_ptr<BatchFitter>>& fitters;
    const std::function<std::unique_ptr<BatchFitter>()>& make_fitter;
    MpscStack<StampBatch>& finished;
    long long sequence = 0;  // the next batch's, the reader's alone
    int reader_token = 0, handoff_token = 0, fit_token = 0;
  } stages{cancelled, options, stopped, pool, source, batches_read, fitters, make_fitter, finished};
  try {
    const auto filters =
        tbb::make_filter<void, StampBatch*>(tbb::filter_mode::serial_in_order,
                                            [st = &stages](tbb::flow_control& fc) -> StampBatch* {
                                              Stages& s = captured(st);
                                              STAMPEDE_TSAN_ACQUIRE(&s.reader_token);
                                              struct TurnEnd {
                                                int* token;
                                                ~TurnEnd() { STAMPEDE_TSAN_RELEASE(token); }
                                              } turn_end{&s.reader_token};
                                              if (s.cancelled.load()) {
                                                fc.stop();
                                                return nullptr;
                                              }
                                              if (s.options.stop && s.options.stop->load()) {
                                                s.stopped = true;
                                                fc.stop();
                                                return nullptr;
                                              }
                                              StampBatch* b = s.pool.take();  // blocks while all are in flight
                                              b->sequence = s.sequence;
                                              if (!s.source.fill(*b) || b->count == 0) {
                                                s.pool.put(b);
                                                fc.stop();
                                                return nullptr;
                                              }
                                              ++s.sequence;
                                              s.batches_read.fetch_add(1);
                                              STAMPEDE_TSAN_RELEASE(b);
                                              return b;
                                            }) &
            tbb::make_filter<StampBatch*, StampBatch*>(tbb::filter_mode::parallel,
                                                       [st = &stages](StampBatch* b) {
                                                         Stages& s = captured(st);
                                                         STAMPEDE_TSAN_ACQUIRE(b);
                                                         auto& f = s.fitters.local();
                                                         if (!f) f = s.make_fitter();
                                                         if (!s.cancelled.load()) f->fit(*b);
                                                         STAMPEDE_TSAN_RELEASE(b);
                                                         STAMPEDE_TSAN_RELEASE(&s.fit_token);
                                                         return b;
                                                       }) &
            tbb::make_filter<StampBatch*, void>(tbb::filter_mode::serial_out_of_order,
                                                [st = &stages](StampBatch* b) {
                                                  Stages& s = captured(st);
                                                  STAMPEDE_TSAN_ACQUIRE(&s.handoff_token);
                                                  STAMPEDE_TSAN_ACQUIRE(b);
                                                  s.finished.push(b);
                                                  STAMPEDE_TSAN_RELEASE(&s.handoff_token);
                                                });
    STAMPEDE_TSAN_RELEASE(&run_start_token);  // the stages and filters exist
    arena.execute([&] { tbb::parallel_pipeline(static_cast<std::size_t>(pool_size), filters); });
  } catch (...) {
    pipeline_error = std::current_exception();
    cancelled.store(true);
  }
  STAMPEDE_TSAN_ACQUIRE(&stages.fit_token);
  STAMPEDE_TSAN_ACQUIRE(&stages.reader_token);
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
