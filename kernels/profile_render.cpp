// Sérsic sub-pixel rendering: the dispatcher over the per-instruction-set builds; see
// profile_render.hpp. The kernels themselves are in profile_render_impl.hpp.
#include "kernels/profile_render.hpp"

#include <algorithm>
#include <cmath>

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

// Built once: the table of function pointers for each set this binary and CPU both support.
struct KernelTable {
  ProfileKernels scalar, sse42, avx2, avx512;
  KernelTable() {
    scalar = profile_kernels_scalar();
#ifdef STAMPEDE_HAVE_SSE42
    if (isa_available(Isa::kSse42)) sse42 = profile_kernels_sse42();
#endif
#ifdef STAMPEDE_HAVE_AVX2
    if (isa_available(Isa::kAvx2)) avx2 = profile_kernels_avx2();
#endif
#ifdef STAMPEDE_HAVE_AVX512
    if (isa_available(Isa::kAvx512)) avx512 = profile_kernels_avx512();
#endif
  }
};

const KernelTable& kernel_table() {
  static const KernelTable table;  // immutable after its thread-safe initialisation
  return table;
}

}  // namespace

const ProfileKernels* profile_kernels_for(Isa isa) {
  if (!isa_available(isa)) return nullptr;
  const KernelTable& t = kernel_table();
  switch (resolve_isa(isa)) {
    case Isa::kSse42: return &t.sse42;
    case Isa::kAvx2: return &t.avx2;
    case Isa::kAvx512: return &t.avx512;
    default: return &t.scalar;
  }
}

const ProfileKernels& profile_kernels(Isa isa) {
  const ProfileKernels* k = profile_kernels_for(isa);
  return k ? *k : kernel_table().scalar;
}

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
