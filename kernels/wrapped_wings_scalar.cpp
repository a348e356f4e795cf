// Scalar reference build of the copies' wing light (no vector flags).
#include "kernels/wrapped_wings_impl.hpp"
#include "kernels/wrapped_wings_isa.hpp"

namespace stampede::kernels {
WrapKernels wrap_kernels_scalar() { return make_wrap_kernels<double>("scalar"); }
}  // namespace stampede::kernels
