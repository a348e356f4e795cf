// Engine throughput (stamps/s) against a plain loop over the single-stamp fitter, on the same
// stamps (the first 320 noise-free GREAT08-mini galaxies, paper defaults), measured side by side:
//   BM_PlainLoop          one Fitter, a for loop
//   BM_Engine/threads:N   run_pipeline: serial reader, N fit threads, writer thread
// Overhead at 1 thread = 1 - engine/plain; speed-up = engine(2) / engine(1).
// Steady-state throughput: 80 batches of 4 stamps, so the last batch's tail on one thread (at most
// 4 of 160 fits per thread) weighs ~1 %, as it does in a survey-sized run; with few batches the
// tail, not the engine, would cap the speed-up.
#include <benchmark/benchmark.h>

#include <string>
#include <vector>

#include "engine/pipeline/pipeline.hpp"
#include "engine/pipeline/stamp_fitter.hpp"
#include "engine/render/psf_kernel.hpp"
#include "great08_stamps.hpp"

namespace {

using namespace stampede;

constexpr int kStamps = 320;
constexpr int kBatchSize = 4;

struct Data {
  std::vector<double> stamps;
  int size = 39;
  FitterOptions options;
  std::shared_ptr<const PsfKernel> psf;
  Data() {
    bench::Great08Stamps g = bench::read_great08_stamps(kStamps);
    stamps = std::move(g.pixels);
    size = g.size;
    options.render.stamp_size = size;
    PsfModel p;
    p.moffat = {3.0, 2.85, 0.0, 0.05, 0.0};
    FftPlanCache plans(FftPlanning::kEstimate);
    std::string err;
    psf = PsfKernel::build(p, GridGeometry(options.render), plans, &err);
  }
};

const Data& data() {
  static const Data d;
  return d;
}

class MemorySource final : public StampSource {
 public:
  explicit MemorySource(const Data& d) : d_(d) {}
  long long total_objects() const override { return kStamps; }
  void skip_to(long long i) override { next_ = i; }
  bool fill(StampBatch& b) override {
    const std::size_t npix = static_cast<std::size_t>(d_.size) * d_.size;
    b.begin(next_);
    while (b.count < b.capacity() && next_ < kStamps) {
      std::span<double> pixels, weights;
      b.observations.add_stamp(d_.size, &pixels, &weights).weighted = false;
      std::copy_n(d_.stamps.data() + next_ * npix, npix, pixels.begin());
      b.records[b.count] = ObjectRecord{};
      b.records[b.count].id = next_++;
      ++b.count;
    }
    return b.count > 0;
  }

 private:
  const Data& d_;
  long long next_ = 0;
};

class CountingSink final : public BatchSink {
 public:
  void write(const StampBatch& b) override { rows += b.count; }
  long long rows = 0;
};

void BM_PlainLoop(benchmark::State& state) {
  const Data& d = data();
  FftPlanCache plans(FftPlanning::kEstimate);
  Fitter fitter(d.options, d.psf, plans);
  const std::size_t npix = static_cast<std::size_t>(d.size) * d.size;
  for (auto _ : state)
    for (int i = 0; i < kStamps; ++i) benchmark::DoNotOptimize(fitter.fit(std::span<const double>(d.stamps).subspan(i * npix, npix)));
  state.SetItemsProcessed(state.iterations() * kStamps);
}
BENCHMARK(BM_PlainLoop)->Unit(benchmark::kMillisecond)->UseRealTime()->MinTime(3.0);

void BM_Engine(benchmark::State& state) {
  const Data& d = data();
  PipelineOptions po;
  po.threads = static_cast<int>(state.range(0));
  po.batch_size = kBatchSize;
  for (auto _ : state) {
    MemorySource source(d);
    CountingSink sink;
    run_pipeline(source, sink, [&] { return std::make_unique<StampFitter>(d.options, d.psf, nullptr, FftPlanning::kEstimate); }, po);
    if (sink.rows != kStamps) state.SkipWithError("rows lost");
  }
  state.SetItemsProcessed(state.iterations() * kStamps);
}
BENCHMARK(BM_Engine)->ArgName("threads")->Arg(1)->Arg(2)->Unit(benchmark::kMillisecond)->UseRealTime()->MinTime(3.0);

}  // namespace

BENCHMARK_MAIN();
