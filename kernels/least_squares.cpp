// Least-squares accumulations; see least_squares.hpp.
#include "kernels/least_squares.hpp"

#include <cstddef>

namespace stampede::kernels {

double weighted_chi2(std::span<const double> data, std::span<const double> model, std::span<const double> weight) {
  double chi2 = 0.0;
  for (std::size_t i = 0; i < data.size(); ++i) {
    if (weight[i] == 0.0) continue;  // masked: its data may be NaN
    const double r = data[i] - model[i];
    chi2 += weight[i] * r * r;
  }
  return chi2;
}

double accumulate_normal_equations(std::span<const double> data, std::span<const double> model,
                                   std::span<const double> weight, const double* const* columns, int ncol,
                                   double* alpha, double* beta) {
  for (int k = 0; k < ncol * ncol; ++k) alpha[k] = 0.0;
  for (int k = 0; k < ncol; ++k) beta[k] = 0.0;
  double chi2 = 0.0;
  for (std::size_t i = 0; i < data.size(); ++i) {
    const double w = weight[i];
    if (w == 0.0) continue;  // masked pixel: contributes nothing, skip the column reads
    const double r = data[i] - model[i];
    chi2 += w * r * r;
    for (int k = 0; k < ncol; ++k) {
      const double wc = w * columns[k][i];
      beta[k] += wc * r;
      for (int l = 0; l <= k; ++l) alpha[k * ncol + l] += wc * columns[l][i];
    }
  }
  for (int k = 0; k < ncol; ++k)
    for (int l = k + 1; l < ncol; ++l) alpha[k * ncol + l] = alpha[l * ncol + k];
  return chi2;
}

}  // namespace stampede::kernels
