// Weighted least-squares accumulations over a stamp: chi^2 and the normal equations, per
// instruction set (isa.hpp), in double. Masked pixels (w == 0) may hold NaN or Inf anywhere: they
// contribute exactly nothing. Sums run in a fixed order for each instruction set (lane partial
// sums, then the lanes, then the tail), so results do not depend on threading; different sets
// agree to rounding.
#pragma once

#include <span>

#include "kernels/isa.hpp"

namespace stampede::kernels {

struct LeastSquaresKernels {
  const char* name = "";
  int lanes = 1;  // doubles per vector
  // chi2 = sum_i w_i (d_i - m_i)^2.
  double (*weighted_chi2)(std::span<const double> data, std::span<const double> model,
                          std::span<const double> weight) = nullptr;
  // Normal equations of the linearised problem in the Numerical Recipes convention:
  //   alpha[k][l] = sum_i w_i c_k[i] c_l[i],  beta[k] = sum_i w_i c_k[i] (d_i - m_i),
  // where c_k = d model / d p_k; alpha is ncol x ncol row-major and exactly symmetric; returns chi2.
  // ncol <= kMaxLeastSquaresColumns.
  double (*normal_equations)(std::span<const double> data, std::span<const double> model,
                             std::span<const double> weight, const double* const* columns, int ncol, double* alpha,
                             double* beta) = nullptr;
};

inline constexpr int kMaxLeastSquaresColumns = 16;

// The kernels for a set; nullptr when it was not compiled in or this CPU lacks it.
const LeastSquaresKernels* least_squares_kernels_for(Isa isa);
// least_squares_kernels_for(isa), or the scalar kernels when that set is unavailable.
const LeastSquaresKernels& least_squares_kernels(Isa isa = Isa::kBest);

// Shorthands through least_squares_kernels(); accumulate_normal_equations throws
// std::invalid_argument for ncol > kMaxLeastSquaresColumns.
double weighted_chi2(std::span<const double> data, std::span<const double> model, std::span<const double> weight);
double accumulate_normal_equations(std::span<const double> data, std::span<const double> model,
                                   std::span<const double> weight, const double* const* columns, int ncol,
                                   double* alpha, double* beta);

}  // namespace stampede::kernels
