// Each profile kernel per instruction set, scalar reference first, on the paper-default model grid
// (240 x 240 sub-pixels: 39 px stamp + 4 px padding at U1 = 5), fiducial bulge or disc (r_e 1.3 px,
// e = (0.2, -0.1)). items_per_second counts sub-pixels (supersampling points for the central block).
//   BM_Value/<isa>/<n>           unit-amplitude image, whole grid, one sample per sub-pixel
//   BM_Derivatives/<isa>/<n>     value + five shape-derivative images, whole grid
//   BM_CentralBlock/<isa>/<n>    the N_u x N_u = 3 x 3 central sub-pixels at U2 = 7 (value + derivatives)
// and the least-squares accumulations of every fit evaluation, per instruction set:
//   BM_WeightedChi2/<isa>, BM_NormalEquations/<isa> (39^2 pixels, 7 parameters)
//   BM_SpectrumFold/<isa>   the Fourier-space block average: 240^2 spectrum folded to 48^2 (U = 5)
#include <benchmark/benchmark.h>

#include <array>
#include <string>
#include <vector>

#include "kernels/aligned_vector.hpp"
#include "kernels/ellipse.hpp"
#include "kernels/least_squares.hpp"
#include "kernels/profile_render.hpp"
#include "kernels/sersic.hpp"
#include "kernels/spectrum_fold.hpp"

namespace {

using namespace stampede::kernels;

constexpr int kGrid = 240;
const SubpixelGrid kSubGrid{kGrid, -4.4, 0.2};  // sub-pixel 0 at data x = -4.4 (4.5 px of margin)

SersicDerivativeBlock fiducial(double n) {
  SersicDerivativeBlock d;
  d.shape.x0 = 19.2;
  d.shape.y0 = 18.7;
  d.shape.q = ellipse_quadratic(0.2, -0.1, 1.3);
  d.shape.b = sersic_b(n);
  d.shape.inv_2n = 0.5 / n;
  d.shape.root = sersic_root_for(n);
  d.shape.u_floor = 0.04 / (3.14159 * 1.3 * 1.3);
  d.amplitude = 10.0;
  ellipse_quadratic_derivatives(0.2, -0.1, 1.3, &d.dq_de1, &d.dq_de2);
  d.du_dr_over_u = -2.0 / 1.3;
  return d;
}

const ProfileKernels* kernels_or_skip(benchmark::State& state, Isa isa) {
  const ProfileKernels* k = profile_kernels_for(isa);
  if (!k) state.SkipWithError("instruction set not available on this CPU or build");
  return k;
}

void BM_Value(benchmark::State& state, Isa isa, double n) {
  const ProfileKernels* k = kernels_or_skip(state, isa);
  if (!k) return;
  const SersicDerivativeBlock d = fiducial(n);
  std::vector<double> out(kGrid * kGrid, 0.0);
  const GridRegion all{0, kGrid, 0, kGrid};
  for (auto _ : state) {
    k->accumulate_value(kSubGrid, all, 1, d.shape, 1.0, out.data());
    benchmark::DoNotOptimize(out.data());
  }
  state.SetItemsProcessed(state.iterations() * kGrid * kGrid);
}

// Value + derivative kernel over `region` at `supersample` points per sub-pixel side; overwrite as
// the renderer's first (bulge) pass over the grid, accumulate as the central block's.
void run_derivatives(benchmark::State& state, Isa isa, double n, const GridRegion& region, int supersample,
                     bool overwrite) {
  const ProfileKernels* k = kernels_or_skip(state, isa);
  if (!k) return;
  const SersicDerivativeBlock d = fiducial(n);
  std::vector<std::vector<double>> img(6, std::vector<double>(kGrid * kGrid, 0.0));
  const std::array<double*, kNumShapeDerivatives> deriv = {img[0].data(), img[1].data(), img[2].data(),
                                                           img[3].data(), img[4].data()};
  for (auto _ : state) {
    k->accumulate_derivatives(kSubGrid, region, supersample, d, img[5].data(), deriv, overwrite);
    benchmark::DoNotOptimize(img[5].data());
  }
  const long long points = static_cast<long long>(region.x_end - region.x_begin) * (region.y_end - region.y_begin) *
                           supersample * supersample;
  state.SetItemsProcessed(state.iterations() * points);
}

void BM_Derivatives(benchmark::State& state, Isa isa, double n) {
  run_derivatives(state, isa, n, GridRegion{0, kGrid, 0, kGrid}, 1, true);
}

void BM_CentralBlock(benchmark::State& state, Isa isa, double n) {
  run_derivatives(state, isa, n, GridRegion{117, 120, 115, 118}, 7, false);
}

void register_profile_benchmarks() {
  for (Isa isa : {Isa::kScalar, Isa::kSse42, Isa::kAvx2, Isa::kAvx512})
    for (double n : {1.0, 4.0}) {
      const std::string suffix = std::string("/") + isa_name(isa) + "/n" + (n == 1.0 ? "1" : "4");
      benchmark::RegisterBenchmark(("BM_Value" + suffix).c_str(), BM_Value, isa, n)->Unit(benchmark::kMicrosecond);
      benchmark::RegisterBenchmark(("BM_Derivatives" + suffix).c_str(), BM_Derivatives, isa, n)
          ->Unit(benchmark::kMicrosecond);
      benchmark::RegisterBenchmark(("BM_CentralBlock" + suffix).c_str(), BM_CentralBlock, isa, n)
          ->Unit(benchmark::kMicrosecond);
    }
}

// The least-squares accumulations of every fit evaluation, 39^2 pixels, 7 columns. No pixel is
// masked, as in the fiducial fits (non-finite values under the mask would add the masked pass; the
// tests cover it).
struct LeastSquaresProblem {  // aligned as the fitter's buffers are
  AlignedVector<double> data, model, weight;
  std::vector<AlignedVector<double>> columns;
  std::array<const double*, 7> column_ptrs{};
  LeastSquaresProblem() : data(39 * 39), model(39 * 39), weight(39 * 39), columns(7, AlignedVector<double>(39 * 39)) {
    for (std::size_t i = 0; i < data.size(); ++i) {
      data[i] = 1.0 + 0.001 * static_cast<double>(i % 97);
      model[i] = 0.9 + 0.002 * static_cast<double>(i % 89);
      weight[i] = 1.0 + 0.01 * static_cast<double>(i % 13);
      for (std::size_t k = 0; k < columns.size(); ++k) columns[k][i] = 0.3 + 0.01 * static_cast<double>((i + 7 * k) % 31);
    }
    for (std::size_t k = 0; k < columns.size(); ++k) column_ptrs[k] = columns[k].data();
  }
};

const LeastSquaresKernels* least_squares_or_skip(benchmark::State& state, Isa isa) {
  const LeastSquaresKernels* k = least_squares_kernels_for(isa);
  if (!k) state.SkipWithError("instruction set not available on this CPU or build");
  return k;
}

void BM_WeightedChi2(benchmark::State& state, Isa isa) {
  const LeastSquaresKernels* k = least_squares_or_skip(state, isa);
  if (!k) return;
  const LeastSquaresProblem p;
  for (auto _ : state) benchmark::DoNotOptimize(k->weighted_chi2(p.data, p.model, p.weight));
  state.SetItemsProcessed(state.iterations() * static_cast<long long>(p.data.size()));
}

void BM_NormalEquations(benchmark::State& state, Isa isa) {
  const LeastSquaresKernels* k = least_squares_or_skip(state, isa);
  if (!k) return;
  const LeastSquaresProblem p;
  double alpha[49], beta[7];
  for (auto _ : state) {
    benchmark::DoNotOptimize(k->normal_equations(p.data, p.model, p.weight, p.column_ptrs.data(), 7, alpha, beta));
    benchmark::DoNotOptimize(alpha);
  }
  state.SetItemsProcessed(state.iterations() * static_cast<long long>(p.data.size()));
}

// The fold of a 240^2 r2c spectrum times the folded PSF kernel down to 48^2 (U = 5), per set.
void BM_SpectrumFold(benchmark::State& state, Isa isa) {
  const SpectrumFoldKernels* f = spectrum_fold_kernels_for(isa);
  if (!f) {
    state.SkipWithError("instruction set not available on this CPU or build");
    return;
  }
  constexpr int n = kGrid, u = 5, m = n / u;
  AlignedVector<double> spectrum(2 * n * (n / 2 + 1)), kernel(2 * n * u * (m / 2 + 1)), out(2 * m * (m / 2 + 1));
  for (std::size_t i = 0; i < spectrum.size(); ++i) spectrum[i] = 1.0 / (1.0 + static_cast<double>(i % 1013));
  for (std::size_t i = 0; i < kernel.size(); ++i) kernel[i] = 0.5 - 0.001 * static_cast<double>(i % 997);
  for (auto _ : state) {
    f->fold(n, u, spectrum.data(), kernel.data(), out.data());
    benchmark::DoNotOptimize(out.data());
  }
  state.SetItemsProcessed(state.iterations() * n * u * (m / 2 + 1));  // complex products
}

void register_least_squares_benchmarks() {
  for (Isa isa : {Isa::kScalar, Isa::kSse42, Isa::kAvx2, Isa::kAvx512}) {
    const std::string suffix = std::string("/") + isa_name(isa);
    benchmark::RegisterBenchmark(("BM_WeightedChi2" + suffix).c_str(), BM_WeightedChi2, isa);
    benchmark::RegisterBenchmark(("BM_NormalEquations" + suffix).c_str(), BM_NormalEquations, isa);
    benchmark::RegisterBenchmark(("BM_SpectrumFold" + suffix).c_str(), BM_SpectrumFold, isa)->Unit(benchmark::kMicrosecond);
  }
}

}  // namespace

int main(int argc, char** argv) {
  register_profile_benchmarks();
  register_least_squares_benchmarks();
  benchmark::Initialize(&argc, argv);
  if (benchmark::ReportUnrecognizedArguments(argc, argv)) return 1;
  benchmark::RunSpecifiedBenchmarks();
  benchmark::Shutdown();
  return 0;
}
