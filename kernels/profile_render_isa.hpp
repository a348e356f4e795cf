// Entry points of the per-instruction-set builds of the profile kernels (profile_render_<isa>.cpp),
// for the dispatcher in profile_render.cpp only.
#pragma once

#include "kernels/profile_render.hpp"

namespace stampede::kernels {

ProfileKernels profile_kernels_scalar();
ProfileKernels profile_kernels_sse42();
ProfileKernels profile_kernels_avx2();
ProfileKernels profile_kernels_avx512();

}  // namespace stampede::kernels
