// SSE4.2 build of the term loop (compiled with -msse4.2): 2 doubles per vector.
#include "kernels/kspace_render_impl.hpp"
#include "kernels/kspace_render_isa.hpp"

namespace stampede::kernels {
KSpaceKernels kspace_kernels_sse42() { return make_kspace_kernels<xsimd::batch<double, xsimd::sse4_2>>("sse4.2"); }
}  // namespace stampede::kernels
