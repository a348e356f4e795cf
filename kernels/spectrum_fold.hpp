// The alias-sum fold of a model-resolution spectrum down to data resolution (the Fourier-space
// block average and decimation of engine/render/fourier_downsampler.hpp), per instruction set.
//
//   out[ky mod M][jx] += sum over rx < U of X[ky][jx + M rx] K[ky][rx][jx]
// for every row ky < n of the n x (n/2 + 1) r2c spectrum X (interleaved re, im), with the folded
// kernel K laid out [ky][rx][jx], jx <= M/2. Columns kx > n/2 missing from the half spectrum are
// conjugates of X at -k. out is the M x (M/2 + 1) half spectrum (interleaved) a c2r transform takes.
#pragma once

#include "kernels/isa.hpp"

namespace stampede::kernels {

struct SpectrumFoldKernels {
  const char* name = "";
  int lanes = 1;  // doubles per vector
  // n: model grid size, u: upsampling (n % u == 0). Every output value is written.
  void (*fold)(int n, int u, const double* spectrum, const double* kernel, double* out) = nullptr;
};

// The kernels for a set; nullptr when it was not compiled in or this CPU lacks it.
const SpectrumFoldKernels* spectrum_fold_kernels_for(Isa isa);
// spectrum_fold_kernels_for(isa), or the scalar kernels when that set is unavailable.
const SpectrumFoldKernels& spectrum_fold_kernels(Isa isa = Isa::kBest);

}  // namespace stampede::kernels
