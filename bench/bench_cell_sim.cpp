// `sim cells`: one metadetection test cell (251 x 251 px of 0.25 arcsec, exponential galaxies of
// hlr 0.5 arcsec, Gaussian PSF FWHM 0.9 arcsec, noise) on one thread, as the shear test draws it:
// the 7 x 7 grid (49 objects) and random positions at 100 per arcmin^2 (~109 objects, blends).
// Beside it the costlier options: a Moffat PSF (wider wings, larger stamps) and bulge + disc
// galaxies (the bulge's stamp reaches the 255 px cap). The metadetect package's own measurement of
// such a cell takes 0.82-0.87 CPU-s (../shared/reference/metadetection.md): drawing must be a
// small fraction of that (target <= 50 ms per cell).
#include <benchmark/benchmark.h>

#include "engine/sim/cell_sim.hpp"

namespace {

using namespace stampede;

void run(benchmark::State& state, const CellSimOptions& o) {
  const CellSimulator sim(o);
  auto ws = sim.make_workspace();
  int cell = 0;
  std::size_t objects = 0;
  sim.simulate(cell, *ws);  // plans made outside the timing
  for (auto _ : state) {
    const SimCell c = sim.simulate(cell++ % 64, *ws);
    objects += c.objects.size();
    benchmark::DoNotOptimize(c.bands[0].image.data());
  }
  state.counters["objects_per_cell"] = static_cast<double>(objects) / static_cast<double>(state.iterations());
}

void BM_CellGrid(benchmark::State& state) { run(state, CellSimOptions{}); }
BENCHMARK(BM_CellGrid)->Unit(benchmark::kMillisecond);

void BM_CellRandom(benchmark::State& state) {
  CellSimOptions o;
  o.layout = CellLayout::kRandom;
  run(state, o);
}
BENCHMARK(BM_CellRandom)->Unit(benchmark::kMillisecond);

void BM_CellGridMoffat(benchmark::State& state) {
  CellSimOptions o;
  o.psf = CellPsfKind::kMoffat;
  run(state, o);
}
BENCHMARK(BM_CellGridMoffat)->Unit(benchmark::kMillisecond);

void BM_CellGridBulgeDisc(benchmark::State& state) {
  CellSimOptions o;
  o.model = CellGalaxyModel::kBulgeDisc;
  run(state, o);
}
BENCHMARK(BM_CellGridBulgeDisc)->Unit(benchmark::kMillisecond);

}  // namespace

BENCHMARK_MAIN();
