// The batch pipeline on its own: every object reaches the sink once, in input order, for any
// thread count and batch size; I/O errors on either side stop the run and surface to the caller.
#include "engine/pipeline/pipeline.hpp"

#include <gtest/gtest.h>

#include <stdexcept>
#include <thread>
#include <vector>

namespace stampede {
namespace {

class CountingSource final : public StampSource {
 public:
  CountingSource(long long n, long long fail_at = -1) : n_(n), fail_at_(fail_at) {}
  long long total_objects() const override { return n_; }
  void skip_to(long long i) override { next_ = i; }
  bool fill(StampBatch& b) override {
    b.begin(next_);
    while (b.count < b.capacity() && next_ < n_) {
      if (next_ == fail_at_) throw std::runtime_error("read error at object " + std::to_string(next_));
      std::span<double> pixels, weights;
      b.observations.add_stamp(1, &pixels, &weights);
      pixels[0] = static_cast<double>(next_);
      b.records[b.count] = ObjectRecord{};
      b.records[b.count].id = next_++;
      ++b.count;
    }
    return b.count > 0;
  }

 private:
  long long n_, fail_at_, next_ = 0;
};

class RecordingSink final : public BatchSink {
 public:
  explicit RecordingSink(long long fail_at = -1) : fail_at_(fail_at) {}
  void write(const StampBatch& b) override {
    for (int k = 0; k < b.count; ++k) {
      if (b.records[k].id == fail_at_) throw std::runtime_error("disk full");
      ids.push_back(b.records[k].id);
      values.push_back(b.records[k].time_us);
    }
  }
  std::vector<long long> ids;
  std::vector<double> values;

 private:
  long long fail_at_;
};

// A "fit" whose duration varies per object, so batches finish out of order.
class SlowSquare final : public BatchFitter {
 public:
  void fit(StampBatch& b) override {
    for (int k = 0; k < b.count; ++k) {
      const double v = b.observations.pixels(b.observations.first_of(k))[0];
      if (static_cast<long long>(v) % 7 == 0) std::this_thread::sleep_for(std::chrono::microseconds(200));
      b.records[k].time_us = v * v;  // the "result"
    }
  }
};

TEST(Pipeline, EveryObjectOnceInOrderForAnyThreadsAndBatchSize) {
  for (int threads : {1, 2, 4})
    for (int batch : {1, 3, 32}) {
      CountingSource source(1000);
      RecordingSink sink;
      PipelineOptions o;
      o.threads = threads;
      o.batch_size = batch;
      long long last_done = -1;
      bool monotone = true;
      const PipelineSummary s = run_pipeline(
          source, sink, [] { return std::make_unique<SlowSquare>(); }, o,
          [&](const PipelineProgress& p) {
            monotone &= p.objects_done > last_done;
            last_done = p.objects_done;
          });
      ASSERT_EQ(sink.ids.size(), 1000u) << threads << " threads, batch " << batch;
      for (long long i = 0; i < 1000; ++i) {
        ASSERT_EQ(sink.ids[i], i);
        ASSERT_EQ(sink.values[i], double(i) * i);
      }
      EXPECT_EQ(s.objects, 1000);
      EXPECT_TRUE(monotone);
      EXPECT_EQ(last_done, 1000);
    }
}

TEST(Pipeline, ResumesFromAnObject) {
  CountingSource source(100);
  source.skip_to(40);
  RecordingSink sink;
  PipelineOptions o;
  o.threads = 2;
  o.batch_size = 8;
  run_pipeline(source, sink, [] { return std::make_unique<SlowSquare>(); }, o);
  ASSERT_EQ(sink.ids.size(), 60u);
  EXPECT_EQ(sink.ids.front(), 40);
  EXPECT_EQ(sink.ids.back(), 99);
}

TEST(Pipeline, ReaderErrorStopsTheRunAndSurfaces) {
  CountingSource source(10000, 517);
  RecordingSink sink;
  PipelineOptions o;
  o.threads = 2;
  o.batch_size = 4;
  EXPECT_THROW(
      {
        try {
          run_pipeline(source, sink, [] { return std::make_unique<SlowSquare>(); }, o);
        } catch (const std::runtime_error& e) {
          EXPECT_NE(std::string(e.what()).find("object 517"), std::string::npos);
          throw;
        }
      },
      std::runtime_error);
  // What was written before the error is a prefix of the input, in order.
  for (std::size_t i = 0; i < sink.ids.size(); ++i) EXPECT_EQ(sink.ids[i], static_cast<long long>(i));
  EXPECT_LE(sink.ids.size(), 517u);
}

TEST(Pipeline, WriterErrorStopsTheRunAndSurfaces) {
  CountingSource source(10000);
  RecordingSink sink(300);
  PipelineOptions o;
  o.threads = 2;
  o.batch_size = 4;
  EXPECT_THROW(run_pipeline(source, sink, [] { return std::make_unique<SlowSquare>(); }, o), std::runtime_error);
  EXPECT_EQ(sink.ids.size(), 300u);
}

}  // namespace
}  // namespace stampede
