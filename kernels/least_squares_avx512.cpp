// AVX-512F build of the least-squares kernels (compiled with -mavx512f -mavx2 -mfma): 8 doubles per
// vector.
#include "kernels/least_squares_impl.hpp"
#include "kernels/least_squares_isa.hpp"

namespace stampede::kernels {
LeastSquaresKernels least_squares_kernels_avx512() { return make_least_squares_kernels<xsimd::batch<double, xsimd::avx512f>>("avx512"); }
}  // namespace stampede::kernels
