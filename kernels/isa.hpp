// The instruction sets the per-pixel kernels are built for, and which of them this process may
// use (compiled in and supported by the CPU). Each kernel family keeps its own dispatch table.
#pragma once

namespace stampede::kernels {

// kBest: the widest set both compiled in and supported by this CPU. kScalar is the reference
// (plain double, no vector instructions); results of different sets agree to a few ulp, so a
// run that must be bitwise reproducible across machines names one set explicitly.
enum class Isa { kBest, kScalar, kSse42, kAvx2, kAvx512 };
const char* isa_name(Isa isa);  // "best", "scalar", "sse4.2", "avx2", "avx512"
bool parse_isa(const char* name, Isa* out);

// Whether `isa` was compiled in and this CPU runs it (kScalar and kBest always).
bool isa_available(Isa isa);
// The concrete set kBest stands for here; any other set is returned as it is.
Isa resolve_isa(Isa isa);

}  // namespace stampede::kernels
