// The scalar reference build of the term loop: plain double lanes, no vector instructions.
#include "kernels/kspace_render_impl.hpp"
#include "kernels/kspace_render_isa.hpp"

namespace stampede::kernels {
KSpaceKernels kspace_kernels_scalar() { return make_kspace_kernels<double>("scalar"); }
}  // namespace stampede::kernels
