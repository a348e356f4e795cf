// AVX-512F build of the profile kernels (compiled with -mavx512f -mavx2 -mfma): 8 doubles per vector.
#include "kernels/profile_render_impl.hpp"
#include "kernels/profile_render_isa.hpp"

namespace stampede::kernels {
ProfileKernels profile_kernels_avx512() { return make_profile_kernels<xsimd::batch<double, xsimd::avx512f>>("avx512"); }
}  // namespace stampede::kernels
