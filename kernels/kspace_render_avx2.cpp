// AVX2 + FMA build of the term loop (compiled with -mavx2 -mfma): 4 doubles per vector.
#include "kernels/kspace_render_impl.hpp"
#include "kernels/kspace_render_isa.hpp"

namespace stampede::kernels {
KSpaceKernels kspace_kernels_avx2() {
  return make_kspace_kernels<xsimd::batch<double, xsimd::fma3<xsimd::avx2>>>("avx2");
}
}  // namespace stampede::kernels
