// Entry points of the per-instruction-set builds of the exact renderer's term loop
// (kspace_render_<isa>.cpp), for the dispatcher in kspace_render.cpp only.
#pragma once

#include "kernels/kspace_render.hpp"

namespace stampede::kernels {

KSpaceKernels kspace_kernels_scalar();
KSpaceKernels kspace_kernels_sse42();
KSpaceKernels kspace_kernels_avx2();
KSpaceKernels kspace_kernels_avx512();

}  // namespace stampede::kernels
