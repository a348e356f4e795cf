// The spectrum fold: the dispatcher over the per-instruction-set builds; see spectrum_fold.hpp. The
// kernel itself is in spectrum_fold_impl.hpp.
#include "kernels/spectrum_fold.hpp"

#include "kernels/isa_dispatch.hpp"
#include "kernels/spectrum_fold_isa.hpp"

namespace stampede::kernels {
namespace {

const IsaDispatch<SpectrumFoldKernels>& table() {
  static const IsaDispatch<SpectrumFoldKernels> t(  // immutable after its thread-safe initialisation
      spectrum_fold_kernels_scalar, STAMPEDE_SSE42_ENTRY(spectrum_fold_kernels_sse42),
      STAMPEDE_AVX2_ENTRY(spectrum_fold_kernels_avx2), STAMPEDE_AVX512_ENTRY(spectrum_fold_kernels_avx512));
  return t;
}

}  // namespace

const SpectrumFoldKernels* spectrum_fold_kernels_for(Isa isa) { return table().find(isa); }

const SpectrumFoldKernels& spectrum_fold_kernels(Isa isa) { return table().get(isa); }

}  // namespace stampede::kernels
