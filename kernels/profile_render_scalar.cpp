// The scalar reference build of the profile kernels: plain double lanes, no vector instructions.
#include "kernels/profile_render_impl.hpp"
#include "kernels/profile_render_isa.hpp"

namespace stampede::kernels {
ProfileKernels profile_kernels_scalar() { return make_profile_kernels<double>("scalar"); }
}  // namespace stampede::kernels
