// AVX-512F build of the term loop (compiled with -mavx512f): 8 doubles per vector, one block.
#include "kernels/kspace_render_impl.hpp"
#include "kernels/kspace_render_isa.hpp"

namespace stampede::kernels {
KSpaceKernels kspace_kernels_avx512() { return make_kspace_kernels<xsimd::batch<double, xsimd::avx512f>>("avx512"); }
}  // namespace stampede::kernels
