// The table behind each kernel family's `<family>_kernels_for(isa)`: one entry per instruction set,
// built once from the family's per-set entry points (those CMake compiled in and this CPU runs).
// Included only by the families' dispatchers (kernels/<family>.cpp), which see the
// STAMPEDE_HAVE_<SET> definitions of the kernels library.
#pragma once

#include "kernels/isa.hpp"

// A per-set entry point where its translation unit was compiled in, nullptr otherwise.
#ifdef STAMPEDE_HAVE_SSE42
#define STAMPEDE_SSE42_ENTRY(f) f
#else
#define STAMPEDE_SSE42_ENTRY(f) nullptr
#endif
#ifdef STAMPEDE_HAVE_AVX2
#define STAMPEDE_AVX2_ENTRY(f) f
#else
#define STAMPEDE_AVX2_ENTRY(f) nullptr
#endif
#ifdef STAMPEDE_HAVE_AVX512
#define STAMPEDE_AVX512_ENTRY(f) f
#else
#define STAMPEDE_AVX512_ENTRY(f) nullptr
#endif

namespace stampede::kernels {

template <class Kernels>
class IsaDispatch {
 public:
  using Make = Kernels (*)();
  IsaDispatch(Make scalar, Make sse42, Make avx2, Make avx512) : scalar_(scalar()) {
    if (sse42 && isa_available(Isa::kSse42)) sse42_ = sse42();
    if (avx2 && isa_available(Isa::kAvx2)) avx2_ = avx2();
    if (avx512 && isa_available(Isa::kAvx512)) avx512_ = avx512();
  }
  // nullptr when `isa` was not compiled in or this CPU lacks it.
  const Kernels* find(Isa isa) const {
    if (!isa_available(isa)) return nullptr;
    switch (resolve_isa(isa)) {
      case Isa::kSse42: return &sse42_;
      case Isa::kAvx2: return &avx2_;
      case Isa::kAvx512: return &avx512_;
      default: return &scalar_;
    }
  }
  // find(isa), or the scalar reference when that set is unavailable.
  const Kernels& get(Isa isa) const {
    const Kernels* k = find(isa);
    return k ? *k : scalar_;
  }

 private:
  Kernels scalar_, sse42_, avx2_, avx512_;
};

}  // namespace stampede::kernels
