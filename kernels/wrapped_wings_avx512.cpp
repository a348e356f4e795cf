// AVX-512F build of the copies' wing light (compiled with -mavx512f): 8 doubles per vector.
#include "kernels/wrapped_wings_impl.hpp"
#include "kernels/wrapped_wings_isa.hpp"

namespace stampede::kernels {
WrapKernels wrap_kernels_avx512() { return make_wrap_kernels<xsimd::batch<double, xsimd::avx512f>>("avx512"); }
}  // namespace stampede::kernels
