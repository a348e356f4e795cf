// The scalar reference build of the spectrum fold: one complex value per step, no vector instructions.
#include "kernels/spectrum_fold_impl.hpp"
#include "kernels/spectrum_fold_isa.hpp"

namespace stampede::kernels {
SpectrumFoldKernels spectrum_fold_kernels_scalar() { return make_spectrum_fold_kernels<double>("scalar"); }
}  // namespace stampede::kernels
