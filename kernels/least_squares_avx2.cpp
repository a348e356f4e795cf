// AVX2 + FMA build of the least-squares kernels (compiled with -mavx2 -mfma): 4 doubles per vector.
#include "kernels/least_squares_impl.hpp"
#include "kernels/least_squares_isa.hpp"

namespace stampede::kernels {
LeastSquaresKernels least_squares_kernels_avx2() { return make_least_squares_kernels<xsimd::batch<double, xsimd::fma3<xsimd::avx2>>>("avx2"); }
}  // namespace stampede::kernels
