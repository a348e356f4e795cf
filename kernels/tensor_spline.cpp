// Cubic splines on a grid; see tensor_spline.hpp.
#include "kernels/tensor_spline.hpp"

#include <algorithm>
#include <cmath>

#include <Eigen/Dense>

namespace stampede::kernels {

SplineWeights::SplineWeights(std::span<const double> nodes) : nodes_(nodes.begin(), nodes.end()) {
  const int n = size();
  if (n == 0 || n > kMaxSplineNodes) return;
  for (int i = 0; i < n; ++i)
    if (!std::isfinite(nodes_[i]) || (i > 0 && !(nodes_[i] > nodes_[i - 1]))) return;
  curvature_.assign(static_cast<std::size_t>(n) * n, 0.0);
  if (n >= 3) {
    // Second derivatives M at the nodes. Interior rows: continuity of the slope,
    //   h_{i-1} M_{i-1} / 6 + (h_{i-1} + h_i) M_i / 3 + h_i M_{i+1} / 6
    //     = (y_{i+1} - y_i) / h_i - (y_i - y_{i-1}) / h_{i-1};
    // end rows: not-a-knot, the third derivative continuous at the second and the last but one
    // node (so a cubic is reproduced exactly); with three nodes M is constant, the parabola.
    // Solved once for every unit node value (the columns of the right-hand side).
    Eigen::MatrixXd a = Eigen::MatrixXd::Zero(n, n), b = Eigen::MatrixXd::Zero(n, n);
    const auto h = [&](int i) { return nodes_[i + 1] - nodes_[i]; };
    for (int i = 1; i + 1 < n; ++i) {
      a(i, i - 1) = h(i - 1) / 6;
      a(i, i) = (h(i - 1) + h(i)) / 3;
      a(i, i + 1) = h(i) / 6;
      b(i, i - 1) = 1 / h(i - 1);
      b(i, i) = -1 / h(i - 1) - 1 / h(i);
      b(i, i + 1) = 1 / h(i);
    }
    if (n == 3) {
      a(0, 0) = a(2, 2) = 1;
      a(0, 1) = a(2, 1) = -1;
    } else {
      a(0, 0) = h(1);
      a(0, 1) = -(h(0) + h(1));
      a(0, 2) = h(0);
      a(n - 1, n - 3) = h(n - 2);
      a(n - 1, n - 2) = -(h(n - 3) + h(n - 2));
      a(n - 1, n - 1) = h(n - 3);
    }
    const Eigen::MatrixXd m = a.partialPivLu().solve(b);
    for (int i = 0; i < n; ++i)
      for (int k = 0; k < n; ++k) curvature_[static_cast<std::size_t>(i) * n + k] = m(i, k);
  }
  ok_ = true;
}

void SplineWeights::at(double x, std::span<double> w) const {
  const int n = size();
  std::fill(w.begin(), w.begin() + n, 0.0);
  if (n == 1) {
    w[0] = 1;
    return;
  }
  const int i = static_cast<int>(std::upper_bound(nodes_.begin() + 1, nodes_.end() - 1, x) - nodes_.begin()) - 1;
  const double h = nodes_[i + 1] - nodes_[i];
  const double b = (x - nodes_[i]) / h, a = 1 - b;
  // s = a y_i + b y_{i+1} + ((a^3 - a) M_i + (b^3 - b) M_{i+1}) h^2 / 6.
  w[i] += a;
  w[i + 1] += b;
  const double ca = (a * a * a - a) * h * h / 6, cb = (b * b * b - b) * h * h / 6;
  for (int k = 0; k < n; ++k)
    w[k] += ca * curvature_[static_cast<std::size_t>(i) * n + k] + cb * curvature_[static_cast<std::size_t>(i + 1) * n + k];
}

TensorSpline::TensorSpline(std::span<const double> x_nodes, std::span<const double> y_nodes,
                           std::span<const double> values, int outputs)
    : outputs_(outputs), x_(x_nodes), y_(y_nodes), values_(values.begin(), values.end()) {
  ok_ = outputs > 0 && x_.ok() && y_.ok() &&
        values.size() == static_cast<std::size_t>(x_.size()) * y_.size() * outputs;
}

void TensorSpline::evaluate(double x, double y, std::span<double> out) const {
  std::fill(out.begin(), out.begin() + outputs_, ok_ ? 0.0 : NAN);
  if (!ok_) return;
  double wx[kMaxSplineNodes], wy[kMaxSplineNodes];
  const int nx = x_.size(), ny = y_.size();
  x_.at(x, std::span<double>(wx, nx));
  y_.at(y, std::span<double>(wy, ny));
  for (int i = 0; i < nx; ++i) {
    if (wx[i] == 0) continue;
    for (int j = 0; j < ny; ++j) {
      const double w = wx[i] * wy[j];
      if (w == 0) continue;
      const double* v = &values_[(static_cast<std::size_t>(i) * ny + j) * outputs_];
      for (int k = 0; k < outputs_; ++k) out[k] += w * v[k];
    }
  }
}

}  // namespace stampede::kernels
