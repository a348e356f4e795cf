// Entry points of the per-instruction-set builds of the copies' wing light
// (wrapped_wings_<isa>.cpp), for the dispatcher in wrapped_wings.cpp only.
#pragma once

#include "kernels/wrapped_wings.hpp"

namespace stampede::kernels {

WrapKernels wrap_kernels_scalar();
WrapKernels wrap_kernels_sse42();
WrapKernels wrap_kernels_avx2();
WrapKernels wrap_kernels_avx512();

}  // namespace stampede::kernels
