// Sérsic sub-pixel rendering: the dispatcher over the per-instruction-set builds; see
// profile_render.hpp. The kernels themselves are in profile_render_impl.hpp.
#include "kernels/profile_render.hpp"

#include <xsimd/xsimd.hpp>

#include <algorithm>
#include <cmath>
#include <cstring>

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

const char* isa_name(Isa isa) {
  switch (isa) {
    case Isa::kBest: return "best";
    case Isa::kScalar: return "scalar";
    case Isa::kSse42: return "sse4.2";
    case Isa::kAvx2: return "avx2";
    case Isa::kAvx512: return "avx512";
  }
  return "?";
}

bool parse_isa(const char* name, Isa* out) {
  for (Isa isa : {Isa::kBest, Isa::kScalar, Isa::kSse42, Isa::kAvx2, Isa::kAvx512})
    if (std::strcmp(name, isa_name(isa)) == 0) {
      *out = isa;
      return true;
    }
  return false;
}

namespace {

// Built once: the table of function pointers for each set this binary and CPU both support.
struct KernelTable {
  ProfileKernels scalar, sse42, avx2, avx512;
  bool has_sse42 = false, has_avx2 = false, has_avx512 = false;
  KernelTable() {
    const auto cpu = xsimd::available_architectures();
    scalar = profile_kernels_scalar();
#ifdef STAMPEDE_HAVE_SSE42
    has_sse42 = cpu.sse4_2;
    if (has_sse42) sse42 = profile_kernels_sse42();
#endif
#ifdef STAMPEDE_HAVE_AVX2
    has_avx2 = cpu.avx2 && cpu.fma3_avx2;
    if (has_avx2) avx2 = profile_kernels_avx2();
#endif
#ifdef STAMPEDE_HAVE_AVX512
    has_avx512 = cpu.avx512f;
    if (has_avx512) avx512 = profile_kernels_avx512();
#endif
    (void)cpu;
  }
};

const KernelTable& kernel_table() {
  static const KernelTable table;  // immutable after its thread-safe initialisation
  return table;
}

}  // namespace

const ProfileKernels* profile_kernels_for(Isa isa) {
  const KernelTable& t = kernel_table();
  switch (isa) {
    case Isa::kBest:
      if (t.has_avx512) return &t.avx512;
      if (t.has_avx2) return &t.avx2;
      if (t.has_sse42) return &t.sse42;
      return &t.scalar;
    case Isa::kScalar: return &t.scalar;
    case Isa::kSse42: return t.has_sse42 ? &t.sse42 : nullptr;
    case Isa::kAvx2: return t.has_avx2 ? &t.avx2 : nullptr;
    case Isa::kAvx512: return t.has_avx512 ? &t.avx512 : nullptr;
  }
  return nullptr;
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
