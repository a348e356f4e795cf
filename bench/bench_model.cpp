// One model evaluation and one model + Jacobian evaluation at the paper's defaults (39 px stamp,
// U1 = 5, N_u = 3, U2 = 7) for a fiducial bulge + disc galaxy.
#include <benchmark/benchmark.h>

#include "engine/render/upsampled_renderer.hpp"
#include "kernels/sersic.hpp"

namespace {

using namespace stampede;

struct Setup {
  FftPlanCache plans{FftPlanning::kMeasure};
  RenderOptions ro;
  std::shared_ptr<const PsfKernel> psf;
  std::unique_ptr<UpsampledRenderer> renderer;
  ParamVector p;
  Setup() {
    PsfModel o;
    o.moffat = {3.0, 2.85, 0.0, 0.05, 0.0};
    std::string err;
    psf = PsfKernel::build(o, GridGeometry(ro), plans, &err);
    renderer = std::make_unique<UpsampledRenderer>(ro, ModelOptions{}, psf, plans);
    p = ParameterSet::default_values();
    p[index(Param::kX0)] = 19.2;
    p[index(Param::kY0)] = 18.7;
    p[index(Param::kE1)] = 0.2;
    p[index(Param::kE2)] = -0.1;
    p[index(Param::kRadius)] = 1.3;
    p[index(Param::kBulgeA)] = 500 / kernels::sersic_flux_per_amplitude(1.3, 4.0);
    p[index(Param::kDiscA)] = 500 / kernels::sersic_flux_per_amplitude(1.3, 1.0);
  }
};

void BM_Model(benchmark::State& state) {
  Setup s;
  std::vector<double> model(39 * 39);
  for (auto _ : state) {
    s.renderer->render(s.p, model);
    benchmark::DoNotOptimize(model.data());
  }
}
BENCHMARK(BM_Model)->Unit(benchmark::kMicrosecond);

void BM_ModelAndJacobian(benchmark::State& state) {
  Setup s;
  std::vector<double> model(39 * 39);
  std::vector<std::vector<double>> jac(7, std::vector<double>(39 * 39));
  std::array<double*, 7> cols;
  for (int k = 0; k < 7; ++k) cols[k] = jac[k].data();
  const std::array<Param, 7> free = {Param::kX0, Param::kY0, Param::kE1, Param::kE2, Param::kRadius, Param::kBulgeA, Param::kDiscA};
  for (auto _ : state) {
    s.renderer->render_with_jacobian(s.p, free, model, cols);
    benchmark::DoNotOptimize(model.data());
  }
}
BENCHMARK(BM_ModelAndJacobian)->Unit(benchmark::kMicrosecond);

}  // namespace

BENCHMARK_MAIN();
