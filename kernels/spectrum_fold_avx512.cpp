// AVX-512F build of the spectrum fold (compiled with -mavx512f -mavx2 -mfma): 4 complex values per
// vector.
#include "kernels/spectrum_fold_impl.hpp"
#include "kernels/spectrum_fold_isa.hpp"

namespace stampede::kernels {
SpectrumFoldKernels spectrum_fold_kernels_avx512() { return make_spectrum_fold_kernels<xsimd::batch<double, xsimd::avx512f>>("avx512"); }
}  // namespace stampede::kernels
