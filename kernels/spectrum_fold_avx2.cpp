// AVX2 + FMA build of the spectrum fold (compiled with -mavx2 -mfma): 2 complex values per vector.
#include "kernels/spectrum_fold_impl.hpp"
#include "kernels/spectrum_fold_isa.hpp"

namespace stampede::kernels {
SpectrumFoldKernels spectrum_fold_kernels_avx2() { return make_spectrum_fold_kernels<xsimd::batch<double, xsimd::fma3<xsimd::avx2>>>("avx2"); }
}  // namespace stampede::kernels
