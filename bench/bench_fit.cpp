// One galaxy fit at the paper's defaults (39 px stamps, U1 = 5, N_u = 3, U2 = 7, padding 4) on
// fiducial GREAT08-like galaxies: the first 16 noise-free GalSim GREAT08-mini stamps (co-elliptical
// bulge + disc, Rgp/Rp = 1.4, Moffat beta 3 FWHM 2.85 e = (0, 0.05)), single thread.
//   BM_Fit/<simd>    time per fit with the profile kernels of that instruction set (scalar = the
//                    reference build); counters: evaluations and Jacobians per fit
//   BM_FitMeasured   the best set with FFTW_MEASURE plans (what `stampede fit` uses with fft_wisdom)
//   BM_FitExact/<period>  renderer = exact, best set (period 0: its rule), beside the upsampled
//                    renderer's BM_Fit in one run; no surrogate (every iteration exact)
//   BM_FitDefault/<snr>   the default fit (renderer = exact with its surrogate) on 64 fiducial
//                    GREAT08-like stamps drawn by the simulator (snr 0: noise-free), beside
//   BM_FitExactOnly/<snr> the same stamps with every iteration exact, and
//   BM_FitUpsampled/<snr> the same stamps with the upsampled renderer
//   BM_FitFromOptimum/<snr>, BM_FitDefaultFromOptimum/<snr>  all-exact / default fits of the same
//                    stamps started at their all-exact optima (the floor of any better start);
//   BM_FitFromOptimumAtJacobian/<snr>  the same, ending at the first Jacobian that meets eps4
#include <benchmark/benchmark.h>

#include <map>
#include <string>
#include <vector>

#include "engine/fit/fitter.hpp"
#include "engine/sim/great08_sim.hpp"
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
  options.render.exact.surrogate = false;
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

// 64 fiducial GREAT08-like stamps (ring pairs, the set's random shear, Moffat beta 3 FWHM 2.85
// e = (0, 0.05)), each at matched-filter S/N snr with unit noise, or noise-free (snr 0).
struct SimStamps {
  std::vector<double> pixels;
  int size = 0, count = 0;
  double sigma = 0;
};

const SimStamps& sim_stamps(int snr) {
  static std::map<int, SimStamps> cache;
  auto it = cache.find(snr);
  if (it != cache.end()) return it->second;
  Great08SimOptions o;
  o.sets = 1;
  o.grid = 8;
  o.seed = 2020;
  o.noise_free = snr == 0;
  o.snr = snr == 0 ? 20 : snr;
  const SimSet set = Great08Simulator(o).simulate_set(0);
  SimStamps s;
  s.size = o.stamp_size;
  s.count = o.grid * o.grid;
  s.sigma = o.noise_free ? 0.0 : o.noise_sigma;
  for (int iy = 0; iy < o.grid; ++iy)
    for (int ix = 0; ix < o.grid; ++ix)
      for (int y = 0; y < s.size; ++y)
        for (int x = 0; x < s.size; ++x)
          s.pixels.push_back(set.image[static_cast<std::size_t>(iy * s.size + y) * set.width + ix * s.size + x]);
  return cache.emplace(snr, std::move(s)).first->second;
}

// from_optimum: each fit started at its own all-exact optimum, what any better start (or any
// surrogate stage, however cheap) could at best leave of a fit's cost.
void run_sim_fits(benchmark::State& state, RendererKind kind, bool surrogate, bool from_optimum = false,
                  bool stop_at_jacobian = false) {
  const SimStamps& s = sim_stamps(static_cast<int>(state.range(0)));
  FitterOptions options;
  options.renderer = kind;
  options.render.stamp_size = s.size;
  options.noise_sigma = s.sigma;
  FftPlanCache plans(FftPlanning::kEstimate);
  std::string err;
  auto psf = make_renderer(kind, options.render, options.model, plans)->prepare_psf(Great08SimOptions::default_psf(), &err);
  if (!psf) {
    state.SkipWithError(err.c_str());
    return;
  }
  const std::size_t npix = static_cast<std::size_t>(s.size) * s.size;
  auto stamp = [&](int i) { return std::span<const double>(s.pixels).subspan(i * npix, npix); };
  std::vector<ParamVector> optima;
  if (from_optimum) {
    FitterOptions exact = options;
    exact.render.exact.surrogate = false;
    Fitter reference(exact, psf, plans);
    for (int i = 0; i < s.count; ++i) optima.push_back(reference.fit(stamp(i)).params);
  }
  options.render.exact.surrogate = surrogate;
  options.lm.stop_at_jacobian = stop_at_jacobian;
  Fitter fitter(options, psf, plans);
  double evaluations = 0, iterations = 0, coarse_evaluations = 0, coarse_iterations = 0;
  long long fits = 0;
  for (auto _ : state) {
    for (int i = 0; i < s.count; ++i) {
      const FitResult r = from_optimum ? fitter.fit_from(stamp(i), {}, optima[i]) : fitter.fit(stamp(i));
      evaluations += r.evaluations;
      iterations += r.iterations;
      coarse_evaluations += r.surrogate_evaluations;
      coarse_iterations += r.surrogate_iterations;
      ++fits;
    }
  }
  state.SetItemsProcessed(fits);
  state.counters["evals_per_fit"] = evaluations / fits;
  state.counters["iters_per_fit"] = iterations / fits;
  state.counters["surrogate_evals_per_fit"] = coarse_evaluations / fits;
  state.counters["surrogate_iters_per_fit"] = coarse_iterations / fits;
  state.counters["ms_per_fit"] = benchmark::Counter(fits * 1e-3, benchmark::Counter::kIsRate | benchmark::Counter::kInvert);
}

void BM_FitDefault(benchmark::State& state) { run_sim_fits(state, RendererKind::kExact, true); }
void BM_FitFromOptimum(benchmark::State& state) { run_sim_fits(state, RendererKind::kExact, false, true); }
void BM_FitDefaultFromOptimum(benchmark::State& state) { run_sim_fits(state, RendererKind::kExact, true, true); }
// All exact from the optimum, ending at the first Jacobian whose Gauss-Newton step predicts less
// than eps4 (the exact stage's rule): one Jacobian render and the errors, the fit's floor.
void BM_FitFromOptimumAtJacobian(benchmark::State& state) { run_sim_fits(state, RendererKind::kExact, false, true, true); }
void BM_FitExactOnly(benchmark::State& state) { run_sim_fits(state, RendererKind::kExact, false); }
void BM_FitUpsampled(benchmark::State& state) { run_sim_fits(state, RendererKind::kUpsampled, false); }
BENCHMARK(BM_FitDefault)->ArgName("snr")->Arg(20)->Arg(0)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_FitExactOnly)->ArgName("snr")->Arg(20)->Arg(0)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_FitUpsampled)->ArgName("snr")->Arg(20)->Arg(0)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_FitFromOptimum)->ArgName("snr")->Arg(20)->Arg(0)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_FitDefaultFromOptimum)->ArgName("snr")->Arg(20)->Arg(0)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_FitFromOptimumAtJacobian)->ArgName("snr")->Arg(20)->Arg(0)->Unit(benchmark::kMillisecond)->UseRealTime();

}  // namespace

BENCHMARK_MAIN();
