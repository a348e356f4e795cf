// SSE4.2 build of the least-squares kernels (compiled with -msse4.2): 2 doubles per vector.
#include "kernels/least_squares_impl.hpp"
#include "kernels/least_squares_isa.hpp"

namespace stampede::kernels {
LeastSquaresKernels least_squares_kernels_sse42() { return make_least_squares_kernels<xsimd::batch<double, xsimd::sse4_2>>("sse4.2"); }
}  // namespace stampede::kernels
