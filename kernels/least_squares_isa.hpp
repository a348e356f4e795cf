// Entry points of the per-instruction-set builds of the least-squares kernels
// (least_squares_<isa>.cpp), for the dispatcher in least_squares.cpp only.
#pragma once

#include "kernels/least_squares.hpp"

namespace stampede::kernels {

LeastSquaresKernels least_squares_kernels_scalar();
LeastSquaresKernels least_squares_kernels_sse42();
LeastSquaresKernels least_squares_kernels_avx2();
LeastSquaresKernels least_squares_kernels_avx512();

}  // namespace stampede::kernels
