// Gaussian RBF interpolation; see rbf_interpolator.hpp.
#include "kernels/rbf_interpolator.hpp"

#include <Eigen/Dense>

#include <cmath>

namespace stampede::kernels {

RbfInterpolator::RbfInterpolator(std::span<const double> nodes, int dims, std::span<const double> values, int outputs,
                                 std::span<const double> length)
    : dims_(dims), outputs_(outputs) {
  if (dims <= 0 || outputs <= 0 || nodes.size() % static_cast<std::size_t>(dims) != 0 ||
      length.size() != static_cast<std::size_t>(dims))
    return;
  n_ = static_cast<int>(nodes.size()) / dims;
  if (n_ == 0 || values.size() != static_cast<std::size_t>(n_) * outputs) return;
  for (double l : length)
    if (!(l > 0)) return;
  nodes_.assign(nodes.begin(), nodes.end());
  for (double l : length) inv_length_.push_back(1.0 / l);
  // Augmented with a linear polynomial (1, x_1 .. x_d), so that constants and slopes are
  // reproduced exactly and the Gaussians only carry the curvature:
  //   [Phi P; P^T 0] [w; c] = [y; 0].
  const int m = dims + 1, size = n_ + m;
  Eigen::MatrixXd a = Eigen::MatrixXd::Zero(size, size);
  for (int i = 0; i < n_; ++i) {
    for (int j = 0; j < n_; ++j) a(i, j) = basis(std::span<const double>(nodes_).subspan(i * dims, dims), j);
    a(i, n_) = a(n_, i) = 1.0;
    for (int d = 0; d < dims; ++d) a(i, n_ + 1 + d) = a(n_ + 1 + d, i) = nodes_[static_cast<std::size_t>(i) * dims + d];
  }
  Eigen::MatrixXd y = Eigen::MatrixXd::Zero(size, outputs);
  for (int i = 0; i < n_; ++i)
    for (int k = 0; k < outputs; ++k) y(i, k) = values[static_cast<std::size_t>(i) * outputs + k];
  const Eigen::FullPivLU<Eigen::MatrixXd> lu(a);
  // Repeated nodes (or too few for the plane) make the system singular.
  if (!lu.isInvertible() || lu.rcond() < 1e-13) return;
  const Eigen::MatrixXd w = lu.solve(y);
  if (!w.allFinite()) return;
  weights_.resize(static_cast<std::size_t>(size) * outputs);
  for (int i = 0; i < size; ++i)
    for (int k = 0; k < outputs; ++k) weights_[static_cast<std::size_t>(i) * outputs + k] = w(i, k);
  ok_ = true;
}

double RbfInterpolator::basis(std::span<const double> x, int node) const {
  double r2 = 0;
  for (int d = 0; d < dims_; ++d) {
    const double t = (x[d] - nodes_[static_cast<std::size_t>(node) * dims_ + d]) * inv_length_[d];
    r2 += t * t;
  }
  return std::exp(-0.5 * r2);
}

void RbfInterpolator::evaluate(std::span<const double> x, std::span<double> out) const {
  for (int k = 0; k < outputs_; ++k) out[k] = 0;
  if (!ok_) {
    for (int k = 0; k < outputs_; ++k) out[k] = NAN;
    return;
  }
  for (int i = 0; i < n_; ++i) {
    const double b = basis(x, i);
    for (int k = 0; k < outputs_; ++k) out[k] += weights_[static_cast<std::size_t>(i) * outputs_ + k] * b;
  }
  for (int j = 0; j <= dims_; ++j) {  // the linear part: c_0 + sum_d c_d x_d
    const double b = j == 0 ? 1.0 : x[j - 1];
    for (int k = 0; k < outputs_; ++k) out[k] += weights_[static_cast<std::size_t>(n_ + j) * outputs_ + k] * b;
  }
}

}  // namespace stampede::kernels
