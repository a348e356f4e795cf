// FFT costs on the model grid, per grid size (U1 x (stamp + 2 padding) sub-pixels per side):
//   BM_ForwardR2C/<n>/<planning>  one n x n r2c transform (FFTW_ESTIMATE vs FFTW_MEASURE); n = 195
//                                 and 235 are the unpadded sizes, 200 and 240 the FFT-friendly ones
//   BM_ForwardR2CFloat/<n>/<planning>  the same in single precision (fftwf), including the
//                                 conversion of the double model image to float that a fit would need
//   BM_ConvolveFullInverse/<n>    forward, multiply by the PSF kernel, n x n inverse, block average:
//                                 the paper's order of operations
//   BM_ConvolveFolded/<n>         forward, then the PSF product, block average and decimation folded
//                                 into the spectrum and a (n/U1)^2 inverse (FourierDownsampler)
#include <benchmark/benchmark.h>
#include <fftw3.h>

#include <cstring>
#include <string>
#include <vector>

#include "engine/render/fft_plans.hpp"
#include "engine/render/fourier_downsampler.hpp"
#include "engine/render/psf_kernel.hpp"
#include "kernels/downsample.hpp"

namespace {

using namespace stampede;

void BM_ForwardR2C(benchmark::State& state) {
  const int n = static_cast<int>(state.range(0));
  const FftPlanning planning = state.range(1) ? FftPlanning::kMeasure : FftPlanning::kEstimate;
  FftConvolver fft(n, planning);
  AlignedBuffer image = fft.make_real_buffer();
  auto* img = static_cast<double*>(image.data());
  for (int i = 0; i < n * n; ++i) img[i] = 1.0 / (1 + i % 97);
  for (auto _ : state) {
    benchmark::DoNotOptimize(fft.transform(img));
    state.PauseTiming();  // transform() may overwrite its input: restore it outside the timing
    for (int i = 0; i < n * n; ++i) img[i] = 1.0 / (1 + i % 97);
    state.ResumeTiming();
  }
  state.SetItemsProcessed(state.iterations() * n * n);
}
BENCHMARK(BM_ForwardR2C)
    ->ArgNames({"n", "measure"})
    ->ArgsProduct({{195, 200, 235, 240}, {0, 1}})
    ->Unit(benchmark::kMicrosecond);

void BM_ForwardR2CFloat(benchmark::State& state) {
  const int n = static_cast<int>(state.range(0));
  const unsigned flags = (state.range(1) ? FFTW_MEASURE : FFTW_ESTIMATE) | FFTW_DESTROY_INPUT;
  const std::size_t npix = static_cast<std::size_t>(n) * n;
  AlignedBuffer source(sizeof(double) * npix), real(sizeof(float) * npix),
      spectrum(sizeof(fftwf_complex) * static_cast<std::size_t>(n) * (n / 2 + 1));
  auto* src = static_cast<double*>(source.data());
  auto* img = static_cast<float*>(real.data());
  fftwf_plan plan = nullptr;
  {
    std::lock_guard<std::mutex> lock(fftw_planner_mutex());
    plan = fftwf_plan_dft_r2c_2d(n, n, img, static_cast<fftwf_complex*>(spectrum.data()), flags);
  }
  for (std::size_t i = 0; i < npix; ++i) src[i] = 1.0 / (1 + static_cast<double>(i % 97));
  for (auto _ : state) {
    for (std::size_t i = 0; i < npix; ++i) img[i] = static_cast<float>(src[i]);
    fftwf_execute(plan);
    benchmark::DoNotOptimize(spectrum.data());
  }
  {
    std::lock_guard<std::mutex> lock(fftw_planner_mutex());
    fftwf_destroy_plan(plan);
  }
  state.SetItemsProcessed(state.iterations() * n * n);
}
BENCHMARK(BM_ForwardR2CFloat)
    ->ArgNames({"n", "measure"})
    ->ArgsProduct({{200, 240}, {0, 1}})
    ->Unit(benchmark::kMicrosecond);

// The paper-default geometry for a stamp of side s at U1 = 5, padding 4 (grid 5 * (s + 8) rounded).
struct Convolution {
  RenderOptions ro;
  FftPlanCache plans{FftPlanning::kMeasure};
  std::shared_ptr<const PsfKernel> psf;
  AlignedBuffer image;
  std::vector<double> stamp;
  explicit Convolution(int stamp_size) {
    ro.stamp_size = stamp_size;
    PsfModel o;
    o.moffat = {3.0, 2.85, 0.0, 0.05, 0.0};
    std::string err;
    psf = PsfKernel::build(o, GridGeometry(ro), plans, &err);
    image = plans.get(GridGeometry(ro).size).make_real_buffer();
    stamp.assign(static_cast<std::size_t>(stamp_size) * stamp_size, 0.0);
  }
  int n() const { return GridGeometry(ro).size; }
  void fill() {
    auto* img = static_cast<double*>(image.data());
    for (int i = 0; i < n() * n(); ++i) img[i] = 1.0 / (1 + i % 97);
  }
};

void BM_ConvolveFullInverse(benchmark::State& state) {
  Convolution c(static_cast<int>(state.range(0)));
  FftConvolver& fft = c.plans.get(c.n());
  const GridGeometry g(c.ro);
  for (auto _ : state) {
    state.PauseTiming();
    c.fill();
    state.ResumeTiming();
    fft.convolve(static_cast<double*>(c.image.data()), c.psf->spectrum());
    kernels::block_average(static_cast<double*>(c.image.data()), g.size, g.upsampling, g.offset, g.stamp_size,
                           c.stamp.data());
    benchmark::DoNotOptimize(c.stamp.data());
  }
  state.counters["grid"] = c.n();
}
BENCHMARK(BM_ConvolveFullInverse)->ArgName("stamp")->Arg(25)->Arg(39)->Arg(48)->Unit(benchmark::kMicrosecond);

void BM_ConvolveFolded(benchmark::State& state) {
  Convolution c(static_cast<int>(state.range(0)));
  FftConvolver& fft = c.plans.get(c.n());
  FourierDownsampler fold(GridGeometry(c.ro));
  for (auto _ : state) {
    state.PauseTiming();
    c.fill();
    state.ResumeTiming();
    fold.apply(fft.transform(static_cast<double*>(c.image.data())), c.psf->folded_spectrum(), c.stamp.data());
    benchmark::DoNotOptimize(c.stamp.data());
  }
  state.counters["grid"] = c.n();
}
BENCHMARK(BM_ConvolveFolded)->ArgName("stamp")->Arg(25)->Arg(39)->Arg(48)->Unit(benchmark::kMicrosecond);

}  // namespace

BENCHMARK_MAIN();
