// AVX2 + FMA build of the profile kernels (compiled with -mavx2 -mfma): 4 doubles per vector.
#include "kernels/profile_render_impl.hpp"
#include "kernels/profile_render_isa.hpp"

namespace stampede::kernels {
ProfileKernels profile_kernels_avx2() {
  return make_profile_kernels<xsimd::batch<double, xsimd::fma3<xsimd::avx2>>>("avx2");
}
}  // namespace stampede::kernels
