// One galaxy fit at the paper's defaults (39 px stamps, U1 = 5, N_u = 3, U2 = 7, padding 4) on
// fiducial GREAT08-like galaxies: the first 16 noise-free GalSim GREAT08-mini stamps (co-elliptical
// bulge + disc, Rgp/Rp = 1.4, Moffat beta 3 FWHM 2.85 e = (0, 0.05)), single thread.
//   BM_Fit/<simd>    time per fit with the profile kernels of that instruction set (scalar = the
//                    reference build); counters: evaluations and Jacobians per fit
//   BM_FitMeasured   the best set with FFTW_MEASURE plans (what `stampede fit` uses with fft_wisdom)
//   BM_FitExact/<period>  renderer = exact, best set (period 0: its rule), beside the upsampled
//                    renderer's BM_Fit in one run
#include <benchmark/benchmark.h>

#include <string>
#include <vector>

#include "engine/fit/fitter.hpp"
#include "engine/render/renderer_factory.hpp"
#include "great08_stamps.hpp"

namespace {

using namespace stampede;

constexpr int kStamps = 16;

const bench::Great08Stamps& stamps() {
  static const bench::Great08Stamps s = bench::read_great08_stamps(kStamps);
  return s;
}

void run_fits(benchmark::State& state, RendererKind kind, kernels::Isa isa, FftPlanning planning, int period = 0) {
  if (!kernels::profile_kernels_for(isa)) {
    state.SkipWithError("instruction set not available");
    return;
  }
  const bench::Great08Stamps& s = stamps();
  FitterOptions options;
  options.renderer = kind;
  options.render.stamp_size = s.size;
  options.render.simd = isa;
  options.render.exact.period = period;
  PsfModel p;
  p.moffat = {3.0, 2.85, 0.0, 0.05, 0.0};
  FftPlanCache plans(planning);
  std::string err;
  auto psf = make_renderer(kind, options.render, options.model, plans)->prepare_psf(p, &err);
  if (!psf) {
    state.SkipWithError(err.c_str());
    return;
  }
  Fitter fitter(options, psf, plans);
  const std::size_t npix = static_cast<std::size_t>(s.size) * s.size;
  double evaluations = 0, iterations = 0;
  long long fits = 0;
  for (auto _ : state) {
    for (int i = 0; i < kStamps; ++i) {
      const FitResult r = fitter.fit(std::span<const double>(s.pixels).subspan(i * npix, npix));
      evaluations += r.evaluations;
      iterations += r.iterations;
      ++fits;
    }
  }
  state.SetItemsProcessed(fits);
  state.counters["evals_per_fit"] = evaluations / fits;
  state.counters["iters_per_fit"] = iterations / fits;
  state.counters["ms_per_fit"] = benchmark::Counter(fits * 1e-3, benchmark::Counter::kIsRate | benchmark::Counter::kInvert);
}

void BM_Fit(benchmark::State& state) {
  run_fits(state, RendererKind::kUpsampled, static_cast<kernels::Isa>(state.range(0)), FftPlanning::kEstimate);
}
BENCHMARK(BM_Fit)
    ->ArgName("isa")
    ->Arg(static_cast<int>(kernels::Isa::kScalar))
    ->Arg(static_cast<int>(kernels::Isa::kBest))
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();

void BM_FitMeasured(benchmark::State& state) {
  run_fits(state, RendererKind::kUpsampled, kernels::Isa::kBest, FftPlanning::kMeasure);
}
BENCHMARK(BM_FitMeasured)->Unit(benchmark::kMillisecond)->UseRealTime();

void BM_FitExact(benchmark::State& state) {
  run_fits(state, RendererKind::kExact, kernels::Isa::kBest, FftPlanning::kEstimate, static_cast<int>(state.range(0)));
}
BENCHMARK(BM_FitExact)->ArgName("period")->Arg(0)->Arg(96)->Unit(benchmark::kMillisecond)->UseRealTime();

}  // namespace

BENCHMARK_MAIN();
