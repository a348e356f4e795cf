// Rank 0's dispatch and the workers' loop; see remote_fitting.hpp.
#include "tools/mpi/remote_fitting.hpp"

#include <mpi.h>

#include <chrono>
#include <cmath>
#include <condition_variable>
#include <cstdio>
#include <deque>
#include <memory>
#include <mutex>
#include <optional>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "app/stamp_fitter_recipe.hpp"
#include "engine/pipeline/stamp_fitter.hpp"
#include "engine/render/psf_cache.hpp"
#include "app/run_config.hpp"
#include "tools/mpi/batch_messages.hpp"
#include "tools/mpi/idle_wait.hpp"

namespace stampede::mpi_driver {

namespace {

// Slot j of a worker talks on these tags; 0-length messages on the batch tag mean stop.
int batch_tag(int slot) { return 100 + slot; }
int rows_tag(int slot) { return 100000 + slot; }
int problems_tag(int slot) { return 200000 + slot; }

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
// run allocates only until its largest batch has been seen). Waits without spinning (idle_wait.hpp).
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

// A pipeline thread's fitter on rank 0: fits the batch in the first free slot, here or remotely.
class DispatchingFitter final : public BatchFitter {
 public:
  DispatchingFitter(std::function<std::unique_ptr<BatchFitter>()> local, SlotPool* pool)
      : make_local_(std::move(local)), pool_(pool) {}
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
        MPI_Request request;
        check(MPI_Irecv(batch.records.data(), static_cast<int>(batch.count * sizeof(ObjectRecord)), MPI_BYTE, s.rank,
                        rows_tag(s.index), MPI_COMM_WORLD, &request),
              "receive rows");
        wait_idle(&request, MPI_STATUS_IGNORE, "receive rows");
        receive_any_size(s.rank, problems_tag(s.index), &message_);  // the problem texts follow the rows
        unpack_problems(message_.data(), message_.size(), &batch);
      }
    } catch (...) {
      pool_->release(s);
      throw;
    }
    pool_->release(s);
  }

 private:
  std::function<std::unique_ptr<BatchFitter>()> make_local_;
  SlotPool* pool_;
  std::unique_ptr<BatchFitter> local_;
  std::vector<char> message_;
};

bool g_distributed = false;
int g_slots = 0;

void broadcast_text(std::string text) {
  long long n = static_cast<long long>(text.size());
  check(MPI_Bcast(&n, 1, MPI_LONG_LONG, 0, MPI_COMM_WORLD), "broadcast");
  if (n > 0) check(MPI_Bcast(text.data(), static_cast<int>(n), MPI_CHAR, 0, MPI_COMM_WORLD), "broadcast");
}

std::string receive_text() {
  long long n = 0;
  check(MPI_Bcast(&n, 1, MPI_LONG_LONG, 0, MPI_COMM_WORLD), "broadcast");
  std::string text(static_cast<std::size_t>(n), '\0');
  if (n > 0) check(MPI_Bcast(text.data(), static_cast<int>(n), MPI_CHAR, 0, MPI_COMM_WORLD), "broadcast");
  return text;
}

}  // namespace

app::FitDistributor rank0_distributor(int ranks, int threads) {
  return [ranks, threads](const app::DistributedRun& run, std::function<std::unique_ptr<BatchFitter>()> local) {
    // The effective options (stamp size and PSF as the input's header made them), one per line,
    // then the driver's own lines (not option keys): slots, and a survey run's tiles and bands.
    std::string text;
    for (const auto& [k, v] : app::effective_options(run.config)) text += k + "=" + v + "\n";
    text += "mpi_slots=" + std::to_string(threads) + "\n";
    for (const std::string& m : run.meds) text += "mpi_meds=" + m + "\n";
    for (const std::string& b : run.bands) text += "mpi_band=" + b + "\n";
    broadcast_text(text);
    g_distributed = true;
    g_slots = threads;
    auto pool = std::make_shared<SlotPool>(ranks, threads);
    app::FitDistribution d;
    d.pipeline_threads = ranks * threads;
    d.make_fitter = [pool, local]() -> std::unique_ptr<BatchFitter> {
      return std::make_unique<DispatchingFitter>(local, pool.get());
    };
    return d;
  };
}

void stop_workers(int ranks) {
  if (!g_distributed) {
    broadcast_text("");  // no run: the workers wait for a configuration
    return;
  }
  for (int r = 1; r < ranks; ++r)
    for (int j = 0; j < g_slots; ++j) check(MPI_Send(nullptr, 0, MPI_BYTE, r, batch_tag(j), MPI_COMM_WORLD), "stop");
}

void run_worker(int /*threads*/) {
  const std::string text = receive_text();
  if (text.empty()) return;
  app::RunConfig cfg;
  int slots = 1;
  std::vector<std::string> meds, bands;
  std::istringstream lines(text);
  for (std::string line; std::getline(lines, line);) {
    const std::size_t eq = line.find('=');
    const std::string key = line.substr(0, eq), value = line.substr(eq + 1);
    if (key == "mpi_slots") {
      slots = std::stoi(value);
    } else if (key == "mpi_meds") {
      meds.push_back(value);
    } else if (key == "mpi_band") {
      bands.push_back(value);
    } else {
      app::set_option(cfg, key, value);
    }
  }
  app::validate(cfg);
  const bool survey = !meds.empty();
  FftPlanCache setup_plans(FftPlanning::kEstimate);
  std::optional<app::StampFitterRecipe> recipe;
  if (!survey) recipe = app::stamp_fitter_recipe(cfg, setup_plans, cfg.psf_from_catalogue);
  auto make_fitter = [&]() -> std::unique_ptr<BatchFitter> {
    if (survey) return app::make_survey_fitter(cfg, meds, bands);
    return recipe->make(FftPlanning::kEstimate);
  };

  auto serve_slot = [&](int j) {
      const std::unique_ptr<BatchFitter> fitter = make_fitter();
      StampBatch batch(cfg.batch_size);
      std::vector<char> message;
      for (;;) {
        receive_any_size(0, batch_tag(j), &message);
        if (message.empty()) return;
        unpack_batch(message.data(), message.size(), &batch);
        fitter->fit(batch);
        check(MPI_Send(batch.records.data(), static_cast<int>(batch.count * sizeof(ObjectRecord)), MPI_BYTE, 0,
                       rows_tag(j), MPI_COMM_WORLD),
              "send rows");
        pack_problems(batch, &message);
        check(MPI_Send(message.data(), static_cast<int>(message.size()), MPI_BYTE, 0, problems_tag(j), MPI_COMM_WORLD),
              "send problems");
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

}  // namespace stampede::mpi_driver
