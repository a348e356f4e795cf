// Least-squares accumulations: the dispatcher over the per-instruction-set builds; see
// least_squares.hpp. The kernels themselves are in least_squares_impl.hpp.
#include "kernels/least_squares.hpp"

#include <stdexcept>

#include "kernels/isa_dispatch.hpp"
#include "kernels/least_squares_isa.hpp"

namespace stampede::kernels {
namespace {

const IsaDispatch<LeastSquaresKernels>& table() {
  static const IsaDispatch<LeastSquaresKernels> t(  // immutable after its thread-safe initialisation
      least_squares_kernels_scalar, STAMPEDE_SSE42_ENTRY(least_squares_kernels_sse42),
      STAMPEDE_AVX2_ENTRY(least_squares_kernels_avx2), STAMPEDE_AVX512_ENTRY(least_squares_kernels_avx512));
  return t;
}

}  // namespace

const LeastSquaresKernels* least_squares_kernels_for(Isa isa) { return table().find(isa); }

const LeastSquaresKernels& least_squares_kernels(Isa isa) { return table().get(isa); }

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
