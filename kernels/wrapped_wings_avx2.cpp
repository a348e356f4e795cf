// AVX2 + FMA build of the copies' wing light (compiled with -mavx2 -mfma): 4 doubles per vector.
#include "kernels/wrapped_wings_impl.hpp"
#include "kernels/wrapped_wings_isa.hpp"

namespace stampede::kernels {
WrapKernels wrap_kernels_avx2() { return make_wrap_kernels<xsimd::batch<double, xsimd::fma3<xsimd::avx2>>>("avx2"); }
}  // namespace stampede::kernels
