// Sérsic sub-pixel rendering: the dispatcher over the per-instruction-set builds; see
// profile_render.hpp. The kernels themselves are in profile_render_impl.hpp.
#include "kernels/profile_render.hpp"

#include <algorithm>
#include <cmath>

#include "kernels/isa_dispatch.hpp"
#include "kernels/profile_render_isa.hpp"

namespace stampede::kernels {

SersicRoot sersic_root_for(double n) {
  if (n == 1.0) return SersicRoot::kSquareRoot;
  if (n == 4.0) return SersicRoot::kEighthRoot;
  return SersicRoot::kGeneralPow;
}

double sersic_value(const SersicBlock& block, double x, double y) {
  const double u = std::max(block.q(x - block.x0, y - block.y0), block.u_floor);
  return std::exp(-block.b * std::pow(u, block.inv_2n));
}

namespace {

const IsaDispatch<ProfileKernels>& table() {
  static const IsaDispatch<ProfileKernels> t(  // immutable after its thread-safe initialisation
      profile_kernels_scalar, STAMPEDE_SSE42_ENTRY(profile_kernels_sse42), STAMPEDE_AVX2_ENTRY(profile_kernels_avx2),
      STAMPEDE_AVX512_ENTRY(profile_kernels_avx512));
  return t;
}

}  // namespace

const ProfileKernels* profile_kernels_for(Isa isa) { return table().find(isa); }

const ProfileKernels& profile_kernels(Isa isa) { return table().get(isa); }

void accumulate_sersic(const SubpixelGrid& grid, const GridRegion& region, int supersample,
                       const SersicBlock& block, double amplitude, double* out) {
  if (!region.empty()) profile_kernels().accumulate_value(grid, region, supersample, block, amplitude, out);
}

void accumulate_sersic_derivatives(const SubpixelGrid& grid, const GridRegion& region, int supersample,
                                   const SersicDerivativeBlock& block, double* value,
                                   const std::array<double*, kNumShapeDerivatives>& derivative) {
  if (!region.empty()) profile_kernels().accumulate_derivatives(grid, region, supersample, block, value, derivative, false);
}

}  // namespace stampede::kernels
