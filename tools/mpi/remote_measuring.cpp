// Rank 0's dispatch and the workers' loop; see remote_measuring.hpp.
#include "tools/mpi/remote_measuring.hpp"

#include <mpi.h>

#include <chrono>
#include <condition_variable>
#include <cstdio>
#include <deque>
#include <memory>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include "app/worker_recipe.hpp"
#include "tools/mpi/batch_messages.hpp"

namespace stampede::mpi_driver {

namespace {

// Slot j of a worker talks on these tags; 0-length messages on the batch tag mean stop.
int batch_tag(int slot) { return 100 + slot; }
int results_tag(int slot) { return 100000 + slot; }

struct Slot {
  int rank = 0;  // 0: fitted here
  int index = 0;
};

// Free places to fit a batch: T local ones, S per worker.
class SlotPool {
 public:
  SlotPool(int ranks, int threads) {
    for (int j = 0; j < threads; ++j)
      for (int r = 0; r < ranks; ++r) free_.push_back({r, j});  // interleaved: every rank gets work early
  }
  Slot acquire() {
    std::unique_lock<std::mutex> lock(mutex_);
    available_.wait(lock, [&] { return !free_.empty(); });
    const Slot s = free_.front();
    free_.pop_front();
    return s;
  }
  void release(Slot s) {
    {
      std::lock_guard<std::mutex> lock(mutex_);
      free_.push_back(s);
    }
    available_.notify_one();
  }

 private:
  std::mutex mutex_;
  std::condition_variable available_;
  std::deque<Slot> free_;
};

void check(int rc, const char* what) {
  if (rc != MPI_SUCCESS) throw std::runtime_error(std::string("MPI: ") + what + " failed");
}

// The next message from `source` on `tag`, whatever its size, into *buffer (grown as needed, so a
// run allocates only until its largest batch has been seen). Waits without spinning: OpenMPI's
// blocking calls busy-poll, which would take a core from the measurements for every waiting thread;
// a batch takes ~0.1 s or more, so checking every 1 ms costs at most ~0.5 % of latency.
void receive_any_size(int source, int tag, std::vector<char>* buffer) {
  MPI_Message message;
  MPI_Status status;
  for (int found = 0;;) {
    check(MPI_Improbe(source, tag, MPI_COMM_WORLD, &found, &message, &status), "probe");
    if (found) break;
    std::this_thread::sleep_for(std::chrono::milliseconds(1));
  }
  int size = 0;
  check(MPI_Get_count(&status, MPI_BYTE, &size), "message size");
  buffer->resize(static_cast<std::size_t>(size));
  check(MPI_Mrecv(buffer->data(), size, MPI_BYTE, &message, MPI_STATUS_IGNORE), "receive");
}

// A pipeline thread's measurer on rank 0: measures the batch in the first free slot, here or on a
// worker.
class DispatchingMeasurer final : public BatchFitter {
 public:
  DispatchingMeasurer(app::MeasurerFactory local, SlotPool* pool) : make_local_(std::move(local)), pool_(pool) {}
  void fit(StampBatch& batch) override {
    const Slot s = pool_->acquire();
    try {
      if (s.rank == 0) {
        if (!local_) local_ = make_local_();
        local_->fit(batch);
      } else {
        pack_batch(batch, &message_);
        check(MPI_Send(message_.data(), static_cast<int>(message_.size()), MPI_BYTE, s.rank, batch_tag(s.index),
                       MPI_COMM_WORLD),
              "send batch");
        receive_any_size(s.rank, results_tag(s.index), &message_);
        unpack_results(message_.data(), message_.size(), &batch);
      }
    } catch (...) {
      pool_->release(s);
      throw;
    }
    pool_->release(s);
  }

 private:
  app::MeasurerFactory make_local_;
  SlotPool* pool_;
  std::unique_ptr<BatchFitter> local_;
  std::vector<char> message_;
};

void broadcast_message(std::vector<char> message) {
  long long n = static_cast<long long>(message.size());
  check(MPI_Bcast(&n, 1, MPI_LONG_LONG, 0, MPI_COMM_WORLD), "broadcast");
  if (n > 0) check(MPI_Bcast(message.data(), static_cast<int>(n), MPI_BYTE, 0, MPI_COMM_WORLD), "broadcast");
}

std::vector<char> receive_broadcast() {
  long long n = 0;
  check(MPI_Bcast(&n, 1, MPI_LONG_LONG, 0, MPI_COMM_WORLD), "broadcast");
  std::vector<char> message(static_cast<std::size_t>(n));
  if (n > 0) check(MPI_Bcast(message.data(), static_cast<int>(n), MPI_BYTE, 0, MPI_COMM_WORLD), "broadcast");
  return message;
}

// A worker's part of one run: S slots, each with the run's measurer, until rank 0 says stop.
void serve_run(const app::WorkerRecipe& recipe, int slots) {
  const app::MeasurerFactory make_measurer = app::worker_measurers(recipe);
  auto serve_slot = [&](int j) {
    const std::unique_ptr<BatchFitter> measurer = make_measurer();
    StampBatch batch(recipe.batch_size);
    std::vector<char> message;
    for (;;) {
      receive_any_size(0, batch_tag(j), &message);
      if (message.empty()) return;
      unpack_batch(message.data(), message.size(), &batch);
      measurer->fit(batch);
      pack_results(batch, &message);
      check(MPI_Send(message.data(), static_cast<int>(message.size()), MPI_BYTE, 0, results_tag(j), MPI_COMM_WORLD),
            "send results");
    }
  };
  std::vector<std::thread> threads;
  for (int j = 0; j < slots; ++j) {
    threads.emplace_back([&, j] {
      try {
        serve_slot(j);
      } catch (const std::exception& e) {
        std::fprintf(stderr, "stampede-mpi: rank worker slot %d: %s\n", j, e.what());
        MPI_Abort(MPI_COMM_WORLD, 1);
      }
    });
  }
  for (auto& t : threads) t.join();
}

}  // namespace

app::Distributor rank0_distributor(int ranks, int threads) {
  return [ranks, threads](const app::WorkerRecipe& recipe, app::MeasurerFactory local) {
    std::vector<char> message;
    pack_recipe(recipe, &message);
    broadcast_message(std::move(message));
    int slots = threads;  // every worker's, whatever its node's cores
    check(MPI_Bcast(&slots, 1, MPI_INT, 0, MPI_COMM_WORLD), "broadcast");
    auto pool = std::make_shared<SlotPool>(ranks, threads);
    app::Distribution d;
    d.pipeline_threads = ranks * threads;
    d.make_measurer = [pool, local]() -> std::unique_ptr<BatchFitter> {
      return std::make_unique<DispatchingMeasurer>(local, pool.get());
    };
    d.finish = [ranks, threads] {  // every slot's pipeline thread has returned: none is in a send
      for (int r = 1; r < ranks; ++r)
        for (int j = 0; j < threads; ++j) check(MPI_Send(nullptr, 0, MPI_BYTE, r, batch_tag(j), MPI_COMM_WORLD), "stop");
    };
    return d;
  };
}

void stop_workers() { broadcast_message({}); }

void run_worker() {
  for (;;) {
    const std::vector<char> message = receive_broadcast();
    if (message.empty()) return;
    int slots = 0;
    check(MPI_Bcast(&slots, 1, MPI_INT, 0, MPI_COMM_WORLD), "broadcast");
    serve_run(unpack_recipe(message.data(), message.size()), slots);
  }
}

}  // namespace stampede::mpi_driver
