// A parallel loop over independent indices on plain std::threads, for the simulator's work
// (set drawing, transform tables). Each worker pulls chunks of indices from an atomic counter and
// owns whatever per-thread state `make_state` returns. Results must depend only on the index, so
// they are identical for any thread count. std::thread and std::atomic are fully visible to
// ThreadSanitizer, unlike the uninstrumented libtbb's task scheduling. The thread count is the
// current oneTBB arena's concurrency, so `--threads` (a task_arena) governs this loop too.
#pragma once

#include <tbb/task_arena.h>

#include <algorithm>
#include <atomic>
#include <exception>
#include <mutex>
#include <thread>
#include <vector>

namespace stampede {

// Calls body(state, i) for every i in [0, n), where state = make_state() is created once per
// worker. The first exception thrown stops the loop (pending indices are skipped) and is rethrown.
template <class MakeState, class Body>
void parallel_indices(long long n, long long chunk, MakeState make_state, Body body) {
  const int threads = static_cast<int>(std::clamp<long long>(tbb::this_task_arena::max_concurrency(), 1, std::max(1LL, n)));
  std::atomic<long long> next{0};
  std::atomic<bool> failed{false};
  std::exception_ptr error;
  std::mutex error_mutex;
  auto worker = [&] {
    try {
      auto state = make_state();
      for (;;) {
        const long long begin = next.fetch_add(chunk);
        if (begin >= n || failed.load()) break;
        for (long long i = begin; i < std::min(n, begin + chunk); ++i) body(state, i);
      }
    } catch (...) {
      std::lock_guard<std::mutex> lock(error_mutex);
      if (!error) error = std::current_exception();
      failed.store(true);
    }
  };
  std::vector<std::thread> pool;
  pool.reserve(static_cast<std::size_t>(threads - 1));
  for (int t = 1; t < threads; ++t) pool.emplace_back(worker);
  worker();
  for (auto& t : pool) t.join();
  if (error) std::rethrow_exception(error);
}

}  // namespace stampede
