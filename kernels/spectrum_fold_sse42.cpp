// SSE4.2 build of the spectrum fold (compiled with -msse4.2): 1 complex value per vector.
#include "kernels/spectrum_fold_impl.hpp"
#include "kernels/spectrum_fold_isa.hpp"

namespace stampede::kernels {
SpectrumFoldKernels spectrum_fold_kernels_sse42() { return make_spectrum_fold_kernels<xsimd::batch<double, xsimd::sse4_2>>("sse4.2"); }
}  // namespace stampede::kernels
