// A joint fit's cost against the number of cutouts (the budget: four epochs <= 4.5x one; results
// in docs/meds.md and docs/multiband.md, "Cost").
// Eight bulge + disc galaxies (half-light radius 0.5-0.7", |e| <= 0.4), each seen in four 48-pixel
// cutouts with DES-like random WCS Jacobians (0.263"/px within 3 %, any rotation, WCS shear <= 0.02)
// and Moffat PSFs of FWHM 0.85-1.05", drawn by the simulator, noise at S/N 30 per cutout; exact
// renderer, single thread, each fit from the first cutout's moments.
//   BM_OneEpoch    the first cutout alone
//   BM_FourEpochs  all four jointly
//   BM_MetacalOneEpoch, BM_MetacalFourEpochs   metacal (metacal_model bd, fixnoise): the five
//                  image sets and their joint fits, Gamma chosen per object
//   BM_MetacalWmomFourEpochs   the same with metacal_model wmom: the image sets' moments on the sky
//   BM_MetacalWmomFourEpochsImagePsf   the same with each PSF given as its image, as a MEDS tile's
//                  PSFEx models give it (Gamma is then searched for, not given by a rule)
//   BM_OneBandFourEpochs, BM_ThreeBandsFourEpochs   multi-band fits: the same galaxies
//                  in three bands of four cutouts each (other frames, PSFs and noise, bulge
//                  fraction scaled 0.5x-1.5x over the bands), one band's or all three jointly
//   ...Joint       the same with every amplitude in the solver (project_amplitudes = false)
//   BM_SkyReconvolution  the Gamma rule alone for four cutouts (its filters built), Moffat PSFs
//   BM_SkyReconvolutionImagePsf  the same with each PSF given as its image (as from PSFEx)
#include <benchmark/benchmark.h>

#include <algorithm>
#include <cmath>
#include <random>
#include <vector>

#include "engine/fit/object_fitter.hpp"
#include "engine/metacal/metacal_fitter.hpp"
#include "engine/sim/sim_renderer.hpp"

namespace {

using namespace stampede;

constexpr int kBox = 48, kGalaxies = 8, kEpochs = 4;

struct Cutout {
  PixelFrame frame;
  PsfModel psf, psf_image;  // psf_image: psf as its 25 x 25 pixel-integrated samples
  std::vector<double> pixels, weight;
};

FitterOptions options(bool project = true) {
  FitterOptions o;
  o.renderer = RendererKind::kExact;
  o.project_amplitudes = project;
  return o;
}

// kGalaxies galaxies seen in `bands` bands of kEpochs cutouts each (cutouts g * bands * kEpochs + b *
// kEpochs + k); a band's bulge fraction is the galaxy's scaled by 0.5 + b / 2 (colours).
std::vector<Cutout> draw_cutouts(int bands) {
  std::vector<Cutout> out;
  std::mt19937 rng(2026);
  std::uniform_real_distribution<double> u(-1, 1);
  std::normal_distribution<double> noise(0, 1);
  for (int g = 0; g < kGalaxies; ++g) {
    const double e1 = 0.28 * u(rng), e2 = 0.28 * u(rng), radius = 0.6 + 0.1 * u(rng), fb0 = 0.5 + 0.5 * u(rng);
    for (int k = 0; k < bands * kEpochs; ++k) {
      const int band = k / kEpochs;
      const double fb = bands > 1 ? std::min(1.0, fb0 * (0.5 + 0.5 * band)) : fb0;
      Cutout c;
      const double angle = M_PI * u(rng), scale = 0.263 * (1 + 0.03 * u(rng)), g1 = 0.02 * u(rng), g2 = 0.02 * u(rng);
      const double co = std::cos(angle), si = std::sin(angle);
      c.frame = {scale * (co * (1 + g1) - si * g2), scale * (co * g2 - si * (1 - g1)), scale * (si * (1 + g1) + co * g2),
                 scale * (si * g2 + co * (1 - g1)), 23.5 + 0.5 * u(rng), 23.5 + 0.5 * u(rng)};
      c.psf.kind = PsfKind::kMoffat;
      c.psf.moffat = {3.0, (0.95 + 0.1 * u(rng)) / 0.263, 0.03 * u(rng), 0.03 * u(rng), 0.0};
      double pe1 = 0, pe2 = 0, pr = 0, x = 0, y = 0;
      kernels::ellipse_parameters(c.frame.to_pixel(kernels::ellipse_quadratic(e1, e2, radius)), &pe1, &pe2, &pr);
      c.frame.to_pixel(0.0, 0.0, &x, &y);
      const SimComponent parts[2] = {{4.0, fb, pr, pe1, pe2, x, y}, {1.0, 1 - fb, pr, pe1, pe2, x, y}};
      std::vector<double> img(kBox * kBox);
      SimWorkspace ws;
      SimRenderer(c.psf, SimRenderer::Options{}).render(parts, kBox, img, ws);
      double sum2 = 0;
      for (double v : img) sum2 += v * v;
      const double flux = 30 / std::sqrt(sum2);  // S/N 30 at unit noise
      c.pixels.resize(img.size());
      for (std::size_t i = 0; i < img.size(); ++i) c.pixels[i] = flux * img[i] + noise(rng);
      c.weight.assign(img.size(), 1.0);
      auto image = std::make_shared<PsfImage>();
      image->nx = image->ny = 25;
      image->pixels.resize(25 * 25);
      image->pixel_integrated = true;
      SimRenderer(c.psf, SimRenderer::Options{}).render_psf(25, 1.0, 12.0, 12.0, true, image->pixels, ws);
      c.psf_image = PsfModel::Image(image);
      out.push_back(std::move(c));
    }
  }
  return out;
}

const std::vector<Cutout>& cutouts() {
  static const std::vector<Cutout> all = draw_cutouts(1);
  return all;
}

constexpr int kBands = 3;
const std::vector<Cutout>& band_cutouts() {
  static const std::vector<Cutout> all = draw_cutouts(kBands);
  return all;
}

// The joint fit of each galaxy's first `bands` bands (4 cutouts each) through ObjectFitter.
void fit_bands(benchmark::State& state, int bands, bool project = true) {
  ObjectFitter fitter(options(project));
  std::vector<BandFit> band_fits(kBands);
  std::vector<Observation> data;
  for (std::size_t i = 0; i < band_cutouts().size(); ++i) {
    const Cutout& c = band_cutouts()[i];
    std::string error;
    data.push_back({c.pixels, c.weight, kBox, c.frame, fitter.renderer_for(kBox).prepare_psf(c.psf, &error), 1.0,
                    static_cast<int>(i / kEpochs) % kBands});
    if (!data.back().psf) return state.SkipWithError(error.c_str());
  }
  long long n = 0;
  double iterations = 0, surrogate_iterations = 0, evaluations = 0;
  for (auto _ : state)
    for (int g = 0; g < kGalaxies; ++g, ++n) {
      const FitResult r = fitter.fit(std::span<const Observation>(data).subspan(g * kBands * kEpochs, bands * kEpochs), bands,
                                     std::span<BandFit>(band_fits).first(static_cast<std::size_t>(bands)));
      iterations += r.iterations;
      surrogate_iterations += r.surrogate_iterations;
      evaluations += r.evaluations + r.surrogate_evaluations;
    }
  state.counters["iters_per_fit"] = iterations / static_cast<double>(n);
  state.counters["surrogate_iters_per_fit"] = surrogate_iterations / static_cast<double>(n);
  state.counters["evals_per_fit"] = evaluations / static_cast<double>(n);
  state.counters["ms_per_object"] = benchmark::Counter(n * 1e-3, benchmark::Counter::kIsRate | benchmark::Counter::kInvert);
}

void fit_epochs(benchmark::State& state, int epochs, bool project = true) {
  ObjectFitter fitter(options(project));
  std::vector<Observation> data;
  for (const Cutout& c : cutouts()) {
    std::string error;
    data.push_back({c.pixels, c.weight, kBox, c.frame, fitter.renderer_for(kBox).prepare_psf(c.psf, &error), 1.0});
    if (!data.back().psf) return state.SkipWithError(error.c_str());
  }
  long long n = 0;
  double iterations = 0, surrogate_iterations = 0;
  for (auto _ : state)
    for (int g = 0; g < kGalaxies; ++g, ++n) {
      const FitResult r = fitter.fit(std::span<const Observation>(data).subspan(g * kEpochs, epochs));
      iterations += r.iterations;
      surrogate_iterations += r.surrogate_iterations;
    }
  state.counters["iters_per_fit"] = iterations / static_cast<double>(n);
  state.counters["surrogate_iters_per_fit"] = surrogate_iterations / static_cast<double>(n);
  state.counters["ms_per_object"] = benchmark::Counter(n * 1e-3, benchmark::Counter::kIsRate | benchmark::Counter::kInvert);
}

void metacal_epochs(benchmark::State& state, int epochs, MetacalModel model = MetacalModel::kBulgeDisc,
                    bool image_psf = false) {
  MetacalOptions mo;
  mo.enabled = true;
  mo.model = model;
  MetacalFitter fitter(options(), mo);
  std::vector<Observation> data;
  for (const Cutout& c : cutouts()) data.push_back({.pixels = c.pixels, .weight = c.weight, .box_size = kBox, .frame = c.frame, .psf_model = image_psf ? &c.psf_image : &c.psf});
  long long n = 0, failed = 0;
  for (auto _ : state)
    for (int g = 0; g < kGalaxies; ++g, ++n) {
      FitResult noshear;
      MetacalRecord record;
      std::uint32_t flags = 0;
      std::string problem;
      fitter.fit(std::span<const Observation>(data).subspan(g * kEpochs, epochs), g, 1, &noshear, &record, &flags, &problem);
      failed += flags != 0;
    }
  state.counters["failed"] = static_cast<double>(failed) / static_cast<double>(n);
  state.counters["ms_per_object"] = benchmark::Counter(n * 1e-3, benchmark::Counter::kIsRate | benchmark::Counter::kInvert);
}

void sky_reconvolution_of(benchmark::State& state, bool image) {
  std::vector<MetacalEpochPsf> psfs;
  for (const Cutout& c : cutouts()) psfs.push_back({image ? &c.psf_image : &c.psf, c.frame, 96});
  MetacalOptions mo;
  long long n = 0;
  double fwhm = 0;
  for (auto _ : state)
    for (int g = 0; g < kGalaxies; ++g, ++n) {
      SkyReconvolution out;
      std::string error;
      if (!sky_reconvolution(std::span<const MetacalEpochPsf>(psfs).subspan(g * kEpochs, kEpochs), mo, &out, &error))
        return state.SkipWithError(error.c_str());
      fwhm += out.fwhm;
    }
  state.counters["gamma_fwhm"] = fwhm / static_cast<double>(n);
  state.counters["ms_per_object"] = benchmark::Counter(n * 1e-3, benchmark::Counter::kIsRate | benchmark::Counter::kInvert);
}

void BM_OneEpoch(benchmark::State& state) { fit_epochs(state, 1); }
void BM_MetacalOneEpoch(benchmark::State& state) { metacal_epochs(state, 1); }
void BM_MetacalFourEpochs(benchmark::State& state) { metacal_epochs(state, kEpochs); }
void BM_MetacalWmomFourEpochs(benchmark::State& state) { metacal_epochs(state, kEpochs, MetacalModel::kWeightedMoments); }
void BM_MetacalWmomFourEpochsImagePsf(benchmark::State& state) {
  metacal_epochs(state, kEpochs, MetacalModel::kWeightedMoments, true);
}
void BM_SkyReconvolution(benchmark::State& state) { sky_reconvolution_of(state, false); }
void BM_SkyReconvolutionImagePsf(benchmark::State& state) { sky_reconvolution_of(state, true); }
void BM_FourEpochs(benchmark::State& state) { fit_epochs(state, kEpochs); }
void BM_OneBandFourEpochs(benchmark::State& state) { fit_bands(state, 1); }
void BM_ThreeBandsFourEpochs(benchmark::State& state) { fit_bands(state, kBands); }
void BM_FourEpochsJoint(benchmark::State& state) { fit_epochs(state, kEpochs, false); }
void BM_OneBandFourEpochsJoint(benchmark::State& state) { fit_bands(state, 1, false); }
void BM_ThreeBandsFourEpochsJoint(benchmark::State& state) { fit_bands(state, kBands, false); }
BENCHMARK(BM_OneEpoch)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_FourEpochs)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_OneBandFourEpochs)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_ThreeBandsFourEpochs)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_FourEpochsJoint)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_OneBandFourEpochsJoint)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_ThreeBandsFourEpochsJoint)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_MetacalOneEpoch)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_MetacalFourEpochs)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_MetacalWmomFourEpochs)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_MetacalWmomFourEpochsImagePsf)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_SkyReconvolution)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_SkyReconvolutionImagePsf)->Unit(benchmark::kMillisecond)->UseRealTime();

}  // namespace

BENCHMARK_MAIN();
