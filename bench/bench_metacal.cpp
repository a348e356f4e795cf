// Metacalibration's cost per object beside one fit, on the 16 fiducial GREAT08-like stamps of
// bench_fit with noise added at S/N 20 (so that fixnoise runs), exact renderer, single thread.
//   BM_OneFit        one fit per stamp (what a run without metacal does)
//   BM_MetacalImages the five images and the fixnoise field's, no fit
//   BM_Metacal       images and the five fits: the cost of a metacal row (metacal_model bd)
//   BM_MetacalGauss  the same with metacal_model gauss (DES Y3's model)
//   BM_MetacalWmom   the images and five weighted moments (metacal_model wmom, DES Y6's): no fit
// The budgets: BM_Metacal / BM_OneFit <= 6, and <= 5 ms a metacal row (docs/metacal.md, "Cost" and
// "Weighted moments").
#include <benchmark/benchmark.h>

#include <cmath>
#include <string>
#include <vector>

#include "engine/common/random_stream.hpp"
#include "engine/metacal/metacal_fitter.hpp"
#include "engine/render/renderer_factory.hpp"
#include "great08_stamps.hpp"

namespace {

using namespace stampede;

constexpr int kStamps = 16;
constexpr double kSnr = 20;

struct NoisyStamps {
  std::vector<double> pixels;
  int size = 0;
  double sigma = 0;
};

// The stamps with Gaussian noise whose sigma gives the first stamp S/N 20 (sqrt(sum I^2) / sigma).
const NoisyStamps& stamps() {
  static const NoisyStamps s = [] {
    const bench::Great08Stamps g = bench::read_great08_stamps(kStamps);
    NoisyStamps n{g.pixels, g.size, 0};
    double sum = 0;
    for (int i = 0; i < g.size * g.size; ++i) sum += g.pixels[i] * g.pixels[i];
    n.sigma = std::sqrt(sum) / kSnr;
    RandomStream rng({2026, 12, 2});
    for (double& v : n.pixels) v += n.sigma * rng.normal();
    return n;
  }();
  return s;
}

FitterOptions options() {
  FitterOptions o;
  o.renderer = RendererKind::kExact;
  o.render.stamp_size = stamps().size;
  o.noise_sigma = stamps().sigma;
  return o;
}

PsfModel psf() {
  PsfModel p;
  p.moffat = {3.0, 2.85, 0.0, 0.05, 0.0};
  return p;
}

std::span<const double> stamp(int i) {
  const std::size_t npix = static_cast<std::size_t>(stamps().size) * stamps().size;
  return std::span<const double>(stamps().pixels).subspan(i * npix, npix);
}

// A grid stamp as metacal takes it (StampFitter): one epoch in its pixel grid.
Observation stamp_epoch(int i, const PsfModel& p) { return {.pixels = stamp(i), .box_size = stamps().size, .psf_model = &p}; }

void BM_OneFit(benchmark::State& state) {
  FftPlanCache plans(FftPlanning::kEstimate);
  std::string err;
  const FitterOptions o = options();
  Fitter fitter(o, make_renderer(o.renderer, o.render, o.model, plans)->prepare_psf(psf(), &err), plans);
  long long n = 0;
  for (auto _ : state)
    for (int i = 0; i < kStamps; ++i, ++n) benchmark::DoNotOptimize(fitter.fit(stamp(i)));
  state.counters["ms_per_object"] = benchmark::Counter(n * 1e-3, benchmark::Counter::kIsRate | benchmark::Counter::kInvert);
}
BENCHMARK(BM_OneFit)->Unit(benchmark::kMillisecond)->UseRealTime();

void BM_MetacalImages(benchmark::State& state) {
  FftPlanCache plans(FftPlanning::kEstimate);
  MetacalFitter mcal(options(), MetacalOptions(), FftPlanning::kEstimate, MetacalFitter::ImageWeight::kUniform);
  const PsfModel p = psf();
  std::string err;
  long long n = 0;
  double v = 0;
  for (auto _ : state)
    for (int i = 0; i < kStamps; ++i, ++n)
      if (!mcal.make_images(stamp_epoch(i, p), i, &v, &err)) return state.SkipWithError(err.c_str());
  state.counters["ms_per_object"] = benchmark::Counter(n * 1e-3, benchmark::Counter::kIsRate | benchmark::Counter::kInvert);
}
BENCHMARK(BM_MetacalImages)->Unit(benchmark::kMillisecond)->UseRealTime();

void metacal_rows(benchmark::State& state, MetacalModel model) {
  FftPlanCache plans(FftPlanning::kEstimate);
  MetacalOptions mo;
  mo.model = model;
  MetacalFitter mcal(options(), mo, FftPlanning::kEstimate, MetacalFitter::ImageWeight::kUniform);
  const PsfModel p = psf();
  std::string problem;
  long long n = 0, failed = 0;
  FitResult r;
  MetacalRecord rec;
  for (auto _ : state)
    for (int i = 0; i < kStamps; ++i, ++n) {
      std::uint32_t flags = 0;
      const Observation epoch = stamp_epoch(i, p);
      mcal.fit({&epoch, 1}, i, 1u << 18, &r, &rec, &flags, &problem);
      failed += flags != 0;
    }
  state.counters["failed"] = static_cast<double>(failed) / static_cast<double>(n);
  state.counters["ms_per_object"] = benchmark::Counter(n * 1e-3, benchmark::Counter::kIsRate | benchmark::Counter::kInvert);
}
void BM_Metacal(benchmark::State& state) { metacal_rows(state, MetacalModel::kBulgeDisc); }
void BM_MetacalGauss(benchmark::State& state) { metacal_rows(state, MetacalModel::kGaussian); }
void BM_MetacalWmom(benchmark::State& state) { metacal_rows(state, MetacalModel::kWeightedMoments); }
BENCHMARK(BM_Metacal)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_MetacalGauss)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_MetacalWmom)->Unit(benchmark::kMillisecond)->UseRealTime();

}  // namespace

BENCHMARK_MAIN();
