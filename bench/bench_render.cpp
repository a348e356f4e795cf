// One render_with_jacobian (model + the 7 Jacobian columns of the paper's fit) on the fiducial
// 39-pixel stamp (Moffat beta 3, FWHM 2.85, e = (0, 0.05); bulge + disc, r = 1.5 px, e = (0.2, 0.1)),
// the exact renderer beside the paper's upsampled one, single thread.
//   BM_Upsampled/<simd>         the paper's renderer (U1 = 5, N_u = 3, U2 = 7, padding 4)
//   BM_Exact/<simd>/<period>/<wrap_rings>  the exact renderer (period 0: the rule, exact_period(39);
//                               wrap_rings 0: no subtraction of the copies' light)
//   BM_ExactModel/<period>      render() alone: one model-only term pass + one inverse FFT
//   BM_SplitC2R/<period>        one split-complex c2r inverse FFT of the period (FFTW_ESTIMATE):
//                               the exact renderer does 7 of them per render_with_jacobian
#include <benchmark/benchmark.h>
#include <fftw3.h>

#include <array>
#include <string>
#include <vector>

#include "engine/render/exact_renderer.hpp"
#include "engine/render/upsampled_renderer.hpp"

namespace {

using namespace stampede;

constexpr int kStamp = 39;
const std::array<Param, 7> kFree = {Param::kX0, Param::kY0, Param::kE1, Param::kE2, Param::kRadius, Param::kBulgeA, Param::kDiscA};

PsfModel fiducial_psf() {
  PsfModel p;
  p.moffat = {3.0, 2.85, 0.0, 0.05, 0.0};
  return p;
}

ParamVector fiducial_params() {
  ParamVector p = ParameterSet::default_values();
  p[index(Param::kX0)] = 19.2;
  p[index(Param::kY0)] = 18.9;
  p[index(Param::kE1)] = 0.2;
  p[index(Param::kE2)] = 0.1;
  p[index(Param::kRadius)] = 1.5;
  p[index(Param::kBulgeA)] = 300.0;
  p[index(Param::kDiscA)] = 30.0;
  return p;
}

struct Images {
  std::vector<double> model = std::vector<double>(kStamp * kStamp);
  std::vector<std::vector<double>> jac = std::vector<std::vector<double>>(7, std::vector<double>(kStamp * kStamp));
  std::array<double*, 7> cols;
  Images() {
    for (int k = 0; k < 7; ++k) cols[k] = jac[k].data();
  }
};

void BM_Upsampled(benchmark::State& state) {
  const auto isa = static_cast<kernels::Isa>(state.range(0));
  if (!kernels::profile_kernels_for(isa)) return state.SkipWithError("instruction set not available");
  RenderOptions ro;
  ro.stamp_size = kStamp;
  ro.simd = isa;
  FftPlanCache plans(FftPlanning::kEstimate);
  std::string err;
  auto psf = PsfKernel::build(fiducial_psf(), GridGeometry(ro), plans, &err);
  UpsampledRenderer r(ro, ModelOptions{}, psf, plans);
  Images im;
  const ParamVector p = fiducial_params();
  for (auto _ : state) benchmark::DoNotOptimize(r.render_with_jacobian(p, kFree, im.model, im.cols));
}
BENCHMARK(BM_Upsampled)->ArgName("simd")->Arg(static_cast<int>(kernels::Isa::kScalar))->Arg(static_cast<int>(kernels::Isa::kBest))->Unit(benchmark::kMicrosecond);

std::unique_ptr<ExactRenderer> make_exact(kernels::Isa isa, int period, int wrap_rings = ExactRenderOptions{}.wrap_rings) {
  RenderOptions ro;
  ro.stamp_size = kStamp;
  ro.simd = isa;
  ro.exact.period = period;
  ro.exact.wrap_rings = wrap_rings;
  auto r = std::make_unique<ExactRenderer>(ro, ModelOptions{});
  std::string error;
  r->set_psf(r->prepare_psf(fiducial_psf(), &error));
  return r;
}

void BM_Exact(benchmark::State& state) {
  const auto isa = static_cast<kernels::Isa>(state.range(0));
  if (!kernels::kspace_kernels_for(isa)) return state.SkipWithError("instruction set not available");
  auto r = make_exact(isa, static_cast<int>(state.range(1)), static_cast<int>(state.range(2)));
  Images im;
  const ParamVector p = fiducial_params();
  for (auto _ : state) benchmark::DoNotOptimize(r->render_with_jacobian(p, kFree, im.model, im.cols));
  state.counters["N"] = r->period();
  state.counters["terms"] = static_cast<double>(r->psf()->terms().entries() * kernels::kKBlock);
}
BENCHMARK(BM_Exact)
    ->ArgNames({"simd", "period", "wrap_rings"})
    ->Args({static_cast<int>(kernels::Isa::kScalar), 0, 6})
    ->Args({static_cast<int>(kernels::Isa::kBest), 0, 6})
    ->Args({static_cast<int>(kernels::Isa::kBest), 0, 0})
    ->Args({static_cast<int>(kernels::Isa::kBest), 96, 6})
    ->Args({static_cast<int>(kernels::Isa::kBest), 160, 0})
    ->Unit(benchmark::kMicrosecond);

void BM_ExactModel(benchmark::State& state) {
  auto r = make_exact(kernels::Isa::kBest, static_cast<int>(state.range(0)));
  Images im;
  const ParamVector p = fiducial_params();
  for (auto _ : state) benchmark::DoNotOptimize(r->render(p, im.model));
  state.counters["N"] = r->period();
}
BENCHMARK(BM_ExactModel)->ArgName("period")->Arg(0)->Arg(72)->Arg(80)->Unit(benchmark::kMicrosecond);

void BM_SplitC2R(benchmark::State& state) {
  const int n = state.range(0) > 0 ? static_cast<int>(state.range(0)) : exact_period(kStamp);
  const int stride = (n / 2 + 1 + 7) / 8 * 8;
  AlignedBuffer re(sizeof(double) * n * stride), im(sizeof(double) * n * stride), out(sizeof(double) * n * n);
  fftw_iodim dims[2] = {{n, stride, n}, {n, 1, 1}};
  fftw_plan plan;
  {
    std::lock_guard<std::mutex> lock(fftw_planner_mutex());
    plan = fftw_plan_guru_split_dft_c2r(2, dims, 0, nullptr, static_cast<double*>(re.data()), static_cast<double*>(im.data()),
                                        static_cast<double*>(out.data()), FFTW_ESTIMATE | FFTW_DESTROY_INPUT);
  }
  for (int i = 0; i < n * stride; ++i) static_cast<double*>(re.data())[i] = static_cast<double*>(im.data())[i] = 1e-3 * (i % 17);
  for (auto _ : state) fftw_execute_split_dft_c2r(plan, static_cast<double*>(re.data()), static_cast<double*>(im.data()), static_cast<double*>(out.data()));
  state.counters["N"] = n;
  std::lock_guard<std::mutex> lock(fftw_planner_mutex());
  fftw_destroy_plan(plan);
}
BENCHMARK(BM_SplitC2R)->ArgName("period")->Arg(0)->Arg(72)->Arg(80)->Unit(benchmark::kMicrosecond);

}  // namespace

BENCHMARK_MAIN();
