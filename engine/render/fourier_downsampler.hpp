// Convolution and block-average downsampling finished in Fourier space, so the inverse transform
// runs at data resolution (M x M) instead of model resolution (n x n = U M x U M).
//
// With X the model spectrum times the PSF kernel (r2c layout, FFTW's 1/n^2 included), the data
// pixel q = (qy, qx) whose first sub-pixel is o + U q (o = offset mod U) is
//   d[q] = sum_j Y[j] exp(+2 pi i j.q / M),   Y[j] = sum_{r in [0,U)^2} X[j + M r] P(jy + M ry) P(jx + M rx),
//   P(k) = exp(2 pi i k o / n) (1/U) sum_{t<U} exp(2 pi i k t / n)
// (the block mean is a product with a Dirichlet kernel; decimation by U is the alias sum over r),
// an exact discrete identity with the real-space block average: results agree to rounding.
// Columns kx > n/2 missing from the half spectrum are conjugates of X at -k.
#pragma once

#include <complex>
#include <vector>

#include "engine/render/fft_plans.hpp"
#include "engine/render/render_options.hpp"
#include "kernels/spectrum_fold.hpp"

namespace stampede {

class FourierDownsampler {
 public:
  // The grid must be a whole number of data pixels: geometry.size % geometry.upsampling == 0.
  // isa: which build of the fold (kernels/spectrum_fold.hpp) to run.
  explicit FourierDownsampler(const GridGeometry& geometry, kernels::Isa isa = kernels::Isa::kBest);
  ~FourierDownsampler();
  FourierDownsampler(const FourierDownsampler&) = delete;
  FourierDownsampler& operator=(const FourierDownsampler&) = delete;

  // The PSF kernel (r2c layout on the model grid) folded with the block average: entries
  // [ky][rx][jx] = kernel(ky, kx = jx + M rx) P(kx) P(ky) (a conjugate where the half spectrum
  // lacks kx). Made once per PSF (PsfKernel holds it, shared by every thread).
  static std::vector<std::complex<double>> fold_kernel(const GridGeometry& geometry, const std::complex<double>* kernel);
  // stamp (stamp_size^2, row-major) = block-averaged inverse transform of spectrum .* kernel,
  // with folded_kernel = fold_kernel(geometry, kernel).
  void apply(const std::complex<double>* spectrum, const std::complex<double>* folded_kernel, double* stamp);

 private:
  int n_, u_, m_, first_pixel_;  // first_pixel_: lattice pixel of the stamp's pixel 0
  int stamp_size_;
  AlignedBuffer folded_;                     // M x (M/2 + 1)
  AlignedBuffer pixels_;                     // M x M
  const kernels::SpectrumFoldKernels* fold_;
  void* plan_ = nullptr;                     // fftw_plan, c2r M x M
};

}  // namespace stampede
