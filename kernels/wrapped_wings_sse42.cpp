// SSE4.2 build of the copies' wing light (compiled with -msse4.2): 2 doubles per vector.
#include "kernels/wrapped_wings_impl.hpp"
#include "kernels/wrapped_wings_isa.hpp"

namespace stampede::kernels {
WrapKernels wrap_kernels_sse42() { return make_wrap_kernels<xsimd::batch<double, xsimd::sse4_2>>("sse4.2"); }
}  // namespace stampede::kernels
