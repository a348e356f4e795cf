// Least-squares accumulations: the dispatcher over the per-instruction-set builds; see
// least_squares.hpp. The kernels themselves are in least_squares_impl.hpp.
#include "kernels/least_squares.hpp"

#include <stdexcept>

#include "kernels/least_squares_isa.hpp"

namespace stampede::kernels {
namespace {

struct KernelTable {
  LeastSquaresKernels scalar, sse42, avx2, avx512;
  KernelTable() {
    scalar = least_squares_kernels_scalar();
#ifdef STAMPEDE_HAVE_SSE42
    if (isa_available(Isa::kSse42)) sse42 = least_squares_kernels_sse42();
#endif
#ifdef STAMPEDE_HAVE_AVX2
    if (isa_available(Isa::kAvx2)) avx2 = least_squares_kernels_avx2();
#endif
#ifdef STAMPEDE_HAVE_AVX512
    if (isa_available(Isa::kAvx512)) avx512 = least_squares_kernels_avx512();
#endif
  }
};

const KernelTable& kernel_table() {
  static const KernelTable table;  // immutable after its thread-safe initialisation
  return table;
}

}  // namespace

const LeastSquaresKernels* least_squares_kernels_for(Isa isa) {
  if (!isa_available(isa)) return nullptr;
  const KernelTable& t = kernel_table();
  switch (resolve_isa(isa)) {
    case Isa::kSse42: return &t.sse42;
    case Isa::kAvx2: return &t.avx2;
    case Isa::kAvx512: return &t.avx512;
    default: return &t.scalar;
  }
}

const LeastSquaresKernels& least_squares_kernels(Isa isa) {
  const LeastSquaresKernels* k = least_squares_kernels_for(isa);
  return k ? *k : kernel_table().scalar;
}

double weighted_chi2(std::span<const double> data, std::span<const double> model, std::span<const double> weight) {
  return least_squares_kernels().weighted_chi2(data, model, weight);
}

double accumulate_normal_equations(std::span<const double> data, std::span<const double> model,
                                   std::span<const double> weight, const double* const* columns, int ncol,
                                   double* alpha, double* beta) {
  if (ncol > kMaxLeastSquaresColumns) throw std::invalid_argument("accumulate_normal_equations: too many columns");
  return least_squares_kernels().normal_equations(data, model, weight, columns, ncol, alpha, beta);
}

}  // namespace stampede::kernels
