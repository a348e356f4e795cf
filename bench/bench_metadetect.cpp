// Metadetection of one cell (the metadetect shear test's: 251 x 251 px of 0.25 arcsec, exponential
// galaxies of hlr 0.5 arcsec on a 7 x 7 grid (49) or at random at 100 per arcmin^2 (~109), a
// Gaussian PSF of FWHM 0.9 arcsec, per-object S/N 20; and the reference package's own test cells,
// S/N 1e6), split into what a cell costs: its five metacal images with fixnoise
// (BM_MetadetectImages), detection on them with our detector and SEP's (BM_MetadetectDetect) and
// the whole cell with wmom (BM_MetadetectCell*, /0 ours, /1 SEP); and whole runs of `stampede metadetect` over
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
#include "engine/metadetect/object_detector.hpp"
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
  std::vector<MetadetectBand> bands;  // each cell's one band
  // reference: the reference package's shear-test cell (`sim cells --reference`): its positions,
  // round galaxies, per-object S/N 1e6 (deep: large isophotes, most galaxies one segment).
  explicit Cells(CellLayout layout, bool reference = false) {
    options.layout = layout;
    if (reference) options.reference_positions = true, options.snr = 1e6, options.shape_noise = 0, options.psf_size = 53;
    const CellSimulator sim(options);
    auto ws = sim.make_workspace();
    for (int k = 0; k < kCells; ++k) cells.push_back(sim.simulate(k, *ws));
    auto img = std::make_shared<PsfImage>();
    img->nx = img->ny = options.psf_size;
    img->pixels = sim.bands()[0].psf;
    psf = PsfModel::Image(img);
    weight.assign(cells[0].bands[0].image.size(), 1.0 / (sim.bands()[0].noise_sigma * sim.bands()[0].noise_sigma));
    for (const SimCell& c : cells) {
      MetadetectBand& b = bands.emplace_back();
      b.image.pixels = c.bands[0].image, b.image.weight = weight, b.image.box_size = options.size;
      b.image.psf_model = &psf;
    }
  }
  Cells(const Cells&) = delete;  // bands point into its own members
  MetadetectCell cell(int k) const {
    MetadetectCell c;
    c.index = k;
    c.bands = std::span<const MetadetectBand>(&bands[static_cast<std::size_t>(k)], 1);
    c.pixel_scale = options.pixel_scale;
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
const Cells& reference_grid_cells() {
  static const Cells c(CellLayout::kGrid, true);
  return c;
}
const Cells& reference_random_cells() {
  static const Cells c(CellLayout::kRandom, true);
  return c;
}

// arg 0: our detector, 1: SEP.
MetadetectOptions with_detector(int detector) {
  MetadetectOptions o;
  o.detection.detector = detector == 0 ? DetectorKind::kTree : DetectorKind::kSep;
  set_detection_pixel_stack(300000);
  return o;
}

void measure_cells(benchmark::State& state, const Cells& cells) {
  CellMeasurer m{with_detector(static_cast<int>(state.range(0)))};
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
BENCHMARK(BM_MetadetectCell)->Arg(0)->Arg(1)->Unit(benchmark::kMillisecond);

void BM_MetadetectCellRandom(benchmark::State& state) { measure_cells(state, random_cells()); }
BENCHMARK(BM_MetadetectCellRandom)->Arg(0)->Arg(1)->Unit(benchmark::kMillisecond);

void BM_MetadetectCellReferenceGrid(benchmark::State& state) { measure_cells(state, reference_grid_cells()); }
BENCHMARK(BM_MetadetectCellReferenceGrid)->Arg(0)->Arg(1)->Unit(benchmark::kMillisecond);

void BM_MetadetectCellReferenceRandom(benchmark::State& state) { measure_cells(state, reference_random_cells()); }
BENCHMARK(BM_MetadetectCellReferenceRandom)->Arg(0)->Arg(1)->Unit(benchmark::kMillisecond);

// The five images with fixnoise alone.
// args: the periodic grid's side (0: the run's, 16 px of margin: 288 for a 251 px cell; 256: a
// power of two, 2.5 px of margin, as a candidate), the arithmetic (0 double, 1 single, the default).
void BM_MetadetectImages(benchmark::State& state) {
  const Cells& cells = grid_cells();
  const int s = cells.options.size;
  const int period = state.range(0) > 0 ? static_cast<int>(state.range(0)) : MetacalImager::padded_size(s, 16);
  MetacalImageSet set(s, FftPlanning::kEstimate, period,
                      state.range(1) ? MetacalImageSet::Precision::kSingle : MetacalImageSet::Precision::kDouble,
                      MetacalImageSet::NoiseDraw::kPairs);
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
BENCHMARK(BM_MetadetectImages)->ArgsProduct({{0, 256}, {0, 1}})->Unit(benchmark::kMillisecond);

// Detection on a cell's image five times (as on its five metacal images), filtering included;
// args: layout (0 the S/N 20 grid, 1 the reference grid, 2 the reference random), detector (0
// ours, 1 SEP). Each iteration takes the next of kCells cells.
void BM_MetadetectDetect(benchmark::State& state) {
  const int layout = static_cast<int>(state.range(0));
  const Cells& cells = layout == 0 ? grid_cells() : layout == 1 ? reference_grid_cells() : reference_random_cells();
  const int s = cells.options.size;
  const MetadetectOptions o = with_detector(static_cast<int>(state.range(1)));
  std::vector<std::vector<float>> images;
  for (const SimCell& c : cells.cells) images.emplace_back(c.bands[0].image.begin(), c.bands[0].image.end());
  const double sigma = 1 / std::sqrt(cells.weight[0]);
  std::vector<Detection> found;
  ObjectDetector detector(o.detection);
  std::string error;
  std::size_t n = 0, k = 0;
  for (auto _ : state) {
    const std::vector<float>& image = images[k++ % images.size()];
    for (int t = 0; t < 5; ++t) detector.detect(image, s, s, sigma, &found, &error);
    n += found.size();
  }
  state.counters["detections"] = static_cast<double>(n) / static_cast<double>(state.iterations());
}
BENCHMARK(BM_MetadetectDetect)->ArgsProduct({{0, 1, 2}, {0, 1}})->Unit(benchmark::kMillisecond);

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
