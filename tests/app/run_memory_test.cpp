// The fit run's memory estimate: the batch pool (3 batches per thread) and a work space per thread,
// and the check that refuses a run the machine cannot hold, naming the thread count.
#include <gtest/gtest.h>

#include "app/run_memory.hpp"
#include "support/error_assertions.hpp"

namespace {

using namespace stampede;

TEST(RunMemory, EstimateIsThePoolOfBatchesAndAWorkSpacePerThread) {
  app::RunConfig cfg;
  cfg.batch_size = 100;
  const app::RunMemoryEstimate one = app::estimate_fit_memory(cfg, 1), eight = app::estimate_fit_memory(cfg, 8);
  EXPECT_EQ(one.batches, 3);
  EXPECT_EQ(eight.batches, 24);
  // Pixels and weights of 100 stamps of 39 x 39 doubles, plus their records and arena entries.
  EXPECT_GT(one.batch_bytes, 100 * 2 * 39 * 39 * 8.0);
  EXPECT_LT(one.batch_bytes, 100 * (2 * 39 * 39 * 8.0 + 4096));
  EXPECT_EQ(eight.per_thread_bytes, one.per_thread_bytes);
  EXPECT_DOUBLE_EQ(eight.total_bytes() - one.total_bytes(), 7 * (3 * one.batch_bytes + one.per_thread_bytes));
  // The default model grid: 5 x 48 sub-pixels a side, 4.6 MB in 10 grids (peak RSS of `stampede fit`
  // grew by 4.7 MB from one thread to two).
  EXPECT_GT(one.per_thread_bytes, 4e6);
  EXPECT_LT(one.per_thread_bytes, 2e7);
}

TEST(RunMemory, CheckRefusesWhatTheMachineCannotHold) {
  app::RunConfig cfg;
  const app::RunMemoryEstimate e = app::estimate_fit_memory(cfg, 64);
  app::check_fit_memory(e, e.total_bytes());
  const std::string msg = stampede::testing::error_of<io::ConfigError>([&] { app::check_fit_memory(e, e.total_bytes() / 2); });
  EXPECT_TRUE(stampede::testing::Contains(msg, "threads = 64: the run would need about"));
  EXPECT_TRUE(stampede::testing::Contains(msg, "use fewer threads or a smaller batch_size"));
}

}  // namespace
