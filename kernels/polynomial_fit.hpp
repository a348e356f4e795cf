// Weighted least-squares polynomial fit y ~ sum_k a_k x^k, k = 0 .. degree (the cubic bias
// curves of the noise-bias calibration: e_fit - e_true against e_true, im3shape section 5.3).
#pragma once

#include <span>
#include <vector>

namespace stampede::kernels {

struct PolynomialFit {
  std::vector<double> coefficients;  // a_0 .. a_degree; empty when the fit is singular
  std::vector<double> errors;        // 1-sigma from the inverse normal matrix (weights = 1/sigma^2)
  double chi2 = 0;                   // sum w (y - fit)^2
  bool ok() const { return !coefficients.empty(); }
  double operator()(double x) const;           // the polynomial
  double derivative(double x) const;           // its slope
};

// Needs at least degree + 1 points with positive weight; weights empty means all 1. Solved in
// the scaled variable x / max|x| for conditioning.
PolynomialFit fit_polynomial(std::span<const double> x, std::span<const double> y, std::span<const double> weight,
                             int degree);

}  // namespace stampede::kernels
