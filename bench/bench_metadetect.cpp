// Metadetection of one cell (the metadetect shear test's: 251 x 251 px of 0.25 arcsec, exponential
// galaxies of hlr 0.5 arcsec on a 7 x 7 grid (49) or at random at 100 per arcmin^2 (~109), a
// Gaussian PSF of FWHM 0.9 arcsec, per-object S/N 20), split into what a cell costs: its five
// metacal images with fixnoise (BM_MetadetectImages), SEP detection on them (BM_MetadetectDetect)
// and the whole cell with wmom (BM_MetadetectCell); and whole runs of `stampede metadetect` over
// 16 and 64 cell files on 1 and 2 threads (BM_MetadetectRun/cells/threads: the time per cell,
// reading and writing included; the 2-thread speed-up is the ratio at the same cells: each thread
// builds its PSF's metacal filters once, which 16 cells on 2 threads do not amortise). The reference package takes 0.82-0.87 CPU-s per
// such cell (../shared/reference/metadetection.md).
#include <benchmark/benchmark.h>

#include <filesystem>
#include <memory>
#include <string>
#include <vector>

#include "app/cell_simulation.hpp"
#include "app/metadetect_run.hpp"
#include "engine/common/random_stream.hpp"
#include "engine/metacal/metacal_image_set.hpp"
#include "engine/metacal/metacal_imager.hpp"
#include "engine/metacal/metacal_options.hpp"
#include "engine/metacal/reconvolution_psf.hpp"
#include "engine/metadetect/cell_measurer.hpp"
#include "engine/metadetect/sep_detection.hpp"
#include "engine/sim/cell_sim.hpp"

namespace {

using namespace stampede;

constexpr int kCells = 16;

struct Cells {
  CellSimOptions options;
  std::vector<SimCell> cells;
  PsfModel psf;
  std::vector<double> weight;
  explicit Cells(CellLayout layout) {
    options.layout = layout;
    const CellSimulator sim(options);
    auto ws = sim.make_workspace();
    for (int k = 0; k < kCells; ++k) cells.push_back(sim.simulate(k, *ws));
    auto img = std::make_shared<PsfImage>();
    img->nx = img->ny = options.psf_size;
    img->pixels = sim.bands()[0].psf;
    psf = PsfModel::Image(img);
    weight.assign(cells[0].bands[0].image.size(), 1.0 / (sim.bands()[0].noise_sigma * sim.bands()[0].noise_sigma));
  }
  MetadetectCell cell(int k) const {
    MetadetectCell c;
    c.index = k;
    c.size = options.size;
    c.pixels = cells[k].bands[0].image;
    c.weight = weight;
    c.pixel_scale = options.pixel_scale;
    c.psf = &psf;
    c.keep_x0 = c.keep_y0 = options.buffer - 0.5;
    c.keep_x1 = c.keep_y1 = options.size - options.buffer - 0.5;
    return c;
  }
};

const Cells& grid_cells() {
  static const Cells c(CellLayout::kGrid);
  return c;
}
const Cells& random_cells() {
  static const Cells c(CellLayout::kRandom);
  return c;
}

void measure_cells(benchmark::State& state, const Cells& cells) {
  CellMeasurer m{MetadetectOptions{}};
  std::vector<MetadetectRow> rows;
  std::string problem;
  m.measure(cells.cell(0), &rows, &problem);  // the PSF's filters made outside the timing, as a run makes them once
  int k = 0;
  std::size_t n = 0;
  for (auto _ : state) {
    rows.clear();
    m.measure(cells.cell(k++ % kCells), &rows, &problem);
    n += rows.size();
  }
  state.counters["rows_per_cell"] = static_cast<double>(n) / static_cast<double>(state.iterations());
}

void BM_MetadetectCell(benchmark::State& state) { measure_cells(state, grid_cells()); }
BENCHMARK(BM_MetadetectCell)->Unit(benchmark::kMillisecond);

void BM_MetadetectCellRandom(benchmark::State& state) { measure_cells(state, random_cells()); }
BENCHMARK(BM_MetadetectCellRandom)->Unit(benchmark::kMillisecond);

// The five images with fixnoise alone.
void BM_MetadetectImages(benchmark::State& state) {
  const Cells& cells = grid_cells();
  const int s = cells.options.size;
  MetacalImageSet set(s, FftPlanning::kEstimate, MetacalImager::padded_size(s, 16));
  MetacalOptions mo;
  mo.enabled = true;
  std::string error;
  const auto filters = reconvolution_filters(cells.psf, mo, set.period(), &error);
  std::vector<double> out(5 * static_cast<std::size_t>(s) * s);
  double variance = 0;
  int k = 0;
  for (auto _ : state) {
    set.make(cells.cells[k % kCells].bands[0].image, cells.weight, WeightKind::kInverseVariance, 0.0, *filters, mo,
             RandomStream({1, static_cast<std::uint64_t>(k), kFixnoisePurpose}), out, &variance);
    ++k;
    benchmark::DoNotOptimize(out.data());
  }
}
BENCHMARK(BM_MetadetectImages)->Unit(benchmark::kMillisecond);

// SEP on the five images of a cell (the noshear image five times: the others cost the same).
void BM_MetadetectDetect(benchmark::State& state) {
  const Cells& cells = grid_cells();
  const int s = cells.options.size;
  const MetadetectOptions o;
  const std::vector<float> filter = detection_filter(o.detection);
  std::vector<float> image(cells.cells[0].bands[0].image.begin(), cells.cells[0].bands[0].image.end());
  const double sigma = 1 / std::sqrt(cells.weight[0]);
  std::vector<Detection> found;
  DetectionScratch scratch;
  std::string error;
  for (auto _ : state)
    for (int t = 0; t < 5; ++t) detect_objects(image, s, s, sigma, o.detection, filter, &scratch, &found, &error);
  state.counters["detections"] = static_cast<double>(found.size());
}
BENCHMARK(BM_MetadetectDetect)->Unit(benchmark::kMillisecond);

constexpr int kRunCells = 64;

// The whole run over the first `cells` of kRunCells files (read, measure, write), per cell; args:
// cells, threads.
void BM_MetadetectRun(benchmark::State& state) {
  const std::string dir = (std::filesystem::temp_directory_path() / "stampede_bench_metadetect").string();
  static bool written = false;
  app::CellOutputOptions out;
  out.cells = kRunCells;
  out.overwrite = true;
  if (!written) app::write_cell_simulation(CellSimOptions{}, out, dir), written = true;
  const int cells = static_cast<int>(state.range(0));
  app::MetadetectRunOptions o;
  for (int k = 0; k < cells; ++k) {
    char name[32];
    std::snprintf(name, sizeof name, "/cell_%04d.fits", k);
    o.inputs.push_back(dir + name);
  }
  o.output = dir + "/out.fits";
  o.overwrite = true;
  o.threads = static_cast<int>(state.range(1));
  for (auto _ : state) app::run_metadetect(o);
  state.counters["cells_per_second"] = benchmark::Counter(cells, benchmark::Counter::kIsIterationInvariantRate);
}
BENCHMARK(BM_MetadetectRun)->ArgsProduct({{16, kRunCells}, {1, 2}})->Unit(benchmark::kMillisecond)->UseRealTime();

}  // namespace

BENCHMARK_MAIN();
