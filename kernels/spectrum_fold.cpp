// The spectrum fold: the dispatcher over the per-instruction-set builds; see spectrum_fold.hpp. The
// kernel itself is in spectrum_fold_impl.hpp.
#include "kernels/spectrum_fold.hpp"

#include "kernels/spectrum_fold_isa.hpp"

namespace stampede::kernels {
namespace {

struct KernelTable {
  SpectrumFoldKernels scalar, sse42, avx2, avx512;
  KernelTable() {
    scalar = spectrum_fold_kernels_scalar();
#ifdef STAMPEDE_HAVE_SSE42
    if (isa_available(Isa::kSse42)) sse42 = spectrum_fold_kernels_sse42();
#endif
#ifdef STAMPEDE_HAVE_AVX2
    if (isa_available(Isa::kAvx2)) avx2 = spectrum_fold_kernels_avx2();
#endif
#ifdef STAMPEDE_HAVE_AVX512
    if (isa_available(Isa::kAvx512)) avx512 = spectrum_fold_kernels_avx512();
#endif
  }
};

const KernelTable& kernel_table() {
  static const KernelTable table;  // immutable after its thread-safe initialisation
  return table;
}

}  // namespace

const SpectrumFoldKernels* spectrum_fold_kernels_for(Isa isa) {
  if (!isa_available(isa)) return nullptr;
  const KernelTable& t = kernel_table();
  switch (resolve_isa(isa)) {
    case Isa::kSse42: return &t.sse42;
    case Isa::kAvx2: return &t.avx2;
    case Isa::kAvx512: return &t.avx512;
    default: return &t.scalar;
  }
}

const SpectrumFoldKernels& spectrum_fold_kernels(Isa isa) {
  const SpectrumFoldKernels* k = spectrum_fold_kernels_for(isa);
  return k ? *k : kernel_table().scalar;
}

}  // namespace stampede::kernels
