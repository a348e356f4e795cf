// The scalar reference build of the least-squares kernels: plain double lanes, no vector instructions.
#include "kernels/least_squares_impl.hpp"
#include "kernels/least_squares_isa.hpp"

namespace stampede::kernels {
LeastSquaresKernels least_squares_kernels_scalar() { return make_least_squares_kernels<double>("scalar"); }
}  // namespace stampede::kernels
