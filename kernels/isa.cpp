// Instruction-set names and availability; see isa.hpp.
#include "kernels/isa.hpp"

#include <xsimd/xsimd.hpp>

#include <cstring>

namespace stampede::kernels {

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

// The STAMPEDE_HAVE_* definitions say which per-ISA translation units CMake compiled in.
struct Availability {
  bool sse42 = false, avx2 = false, avx512 = false;
  Availability() {
    const auto cpu = xsimd::available_architectures();
#ifdef STAMPEDE_HAVE_SSE42
    sse42 = cpu.sse4_2;
#endif
#ifdef STAMPEDE_HAVE_AVX2
    avx2 = cpu.avx2 && cpu.fma3_avx2;
#endif
#ifdef STAMPEDE_HAVE_AVX512
    avx512 = cpu.avx512f;
#endif
    (void)cpu;
  }
};

const Availability& availability() {
  static const Availability a;  // immutable after its thread-safe initialisation
  return a;
}

}  // namespace

bool isa_available(Isa isa) {
  const Availability& a = availability();
  switch (isa) {
    case Isa::kBest:
    case Isa::kScalar: return true;
    case Isa::kSse42: return a.sse42;
    case Isa::kAvx2: return a.avx2;
    case Isa::kAvx512: return a.avx512;
  }
  return false;
}

Isa resolve_isa(Isa isa) {
  if (isa != Isa::kBest) return isa;
  for (Isa widest : {Isa::kAvx512, Isa::kAvx2, Isa::kSse42})
    if (isa_available(widest)) return widest;
  return Isa::kScalar;
}

}  // namespace stampede::kernels
