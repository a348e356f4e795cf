// Polynomial least squares; see polynomial_fit.hpp.
#include "kernels/polynomial_fit.hpp"

#include <Eigen/Dense>

#include <algorithm>
#include <cmath>

namespace stampede::kernels {

double PolynomialFit::operator()(double x) const {
  double v = 0;
  for (auto it = coefficients.rbegin(); it != coefficients.rend(); ++it) v = v * x + *it;
  return v;
}

double PolynomialFit::derivative(double x) const {
  double v = 0;
  for (std::size_t k = coefficients.size(); k-- > 1;) v = v * x + static_cast<double>(k) * coefficients[k];
  return v;
}

PolynomialFit fit_polynomial(std::span<const double> x, std::span<const double> y, std::span<const double> weight,
                             int degree) {
  PolynomialFit out;
  const int p = degree + 1;
  if (degree < 0 || x.size() != y.size() || (!weight.empty() && weight.size() != x.size())) return out;
  double scale = 0;
  for (double v : x) scale = std::max(scale, std::abs(v));
  if (!(scale > 0)) scale = 1;
  Eigen::MatrixXd a = Eigen::MatrixXd::Zero(p, p);
  Eigen::VectorXd b = Eigen::VectorXd::Zero(p);
  int used = 0;
  std::vector<double> powers(static_cast<std::size_t>(p));
  for (std::size_t i = 0; i < x.size(); ++i) {
    const double w = weight.empty() ? 1.0 : weight[i];
    if (!(w > 0) || !std::isfinite(x[i]) || !std::isfinite(y[i])) continue;
    ++used;
    powers[0] = 1;
    for (int k = 1; k < p; ++k) powers[k] = powers[k - 1] * (x[i] / scale);
    for (int k = 0; k < p; ++k) {
      b(k) += w * powers[k] * y[i];
      for (int l = 0; l < p; ++l) a(k, l) += w * powers[k] * powers[l];
    }
  }
  if (used < p) return out;
  const Eigen::FullPivLU<Eigen::MatrixXd> lu(a);
  if (!lu.isInvertible()) return out;
  const Eigen::VectorXd s = lu.solve(b);
  const Eigen::MatrixXd cov = lu.inverse();
  out.coefficients.resize(static_cast<std::size_t>(p));
  out.errors.resize(static_cast<std::size_t>(p));
  for (int k = 0; k < p; ++k) {
    const double unscale = std::pow(scale, -k);  // a_k = s_k / scale^k
    out.coefficients[k] = s(k) * unscale;
    out.errors[k] = std::sqrt(std::max(0.0, cov(k, k))) * unscale;
  }
  for (std::size_t i = 0; i < x.size(); ++i) {
    const double w = weight.empty() ? 1.0 : weight[i];
    if (!(w > 0) || !std::isfinite(x[i]) || !std::isfinite(y[i])) continue;
    const double r = y[i] - out(x[i]);
    out.chi2 += w * r * r;
  }
  return out;
}

}  // namespace stampede::kernels
