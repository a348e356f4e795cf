// Weighted least-squares accumulations over a stamp: chi^2 and the normal equations.
// Accumulation is always in double, in pixel order, so results do not depend on threading.
#pragma once

#include <span>

namespace stampede::kernels {

// chi2 = sum_i w_i (d_i - m_i)^2 over pixels with w_i != 0 (masked pixels may hold NaN).
double weighted_chi2(std::span<const double> data, std::span<const double> model, std::span<const double> weight);

// Normal equations of the linearised problem in the Numerical Recipes convention:
//   alpha[k][l] = sum_i w_i c_k[i] c_l[i],  beta[k] = sum_i w_i c_k[i] (d_i - m_i),
// where c_k = d model / d p_k. alpha is ncol x ncol row-major. Returns chi2.
double accumulate_normal_equations(std::span<const double> data, std::span<const double> model,
                                   std::span<const double> weight, const double* const* columns, int ncol,
                                   double* alpha, double* beta);

}  // namespace stampede::kernels
