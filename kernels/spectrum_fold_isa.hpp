// Entry points of the per-instruction-set builds of the spectrum fold (spectrum_fold_<isa>.cpp), for
// the dispatcher in spectrum_fold.cpp only.
#pragma once

#include "kernels/spectrum_fold.hpp"

namespace stampede::kernels {

SpectrumFoldKernels spectrum_fold_kernels_scalar();
SpectrumFoldKernels spectrum_fold_kernels_sse42();
SpectrumFoldKernels spectrum_fold_kernels_avx2();
SpectrumFoldKernels spectrum_fold_kernels_avx512();

}  // namespace stampede::kernels
