// SSE4.2 build of the profile kernels (compiled with -msse4.2): 2 doubles per vector.
#include "kernels/profile_render_impl.hpp"
#include "kernels/profile_render_isa.hpp"

namespace stampede::kernels {
ProfileKernels profile_kernels_sse42() { return make_profile_kernels<xsimd::batch<double, xsimd::sse4_2>>("sse4.2"); }
}  // namespace stampede::kernels
