// Cubic spline interpolation on a rectangular grid in two dimensions, several outputs at once (the
// noise-bias calibration's interpolation of bias coefficients between its grid nodes). Along each
// axis the interpolant is the not-a-knot cubic spline through the nodes (third derivative
// continuous at the second and last-but-one nodes, so any cubic is reproduced exactly; three nodes
// give the parabola, two the line, one the constant); in two dimensions the tensor product of the
// two. Not the natural spline: its zero curvature at the ends is wrong where bias coefficients curve
// most, at the grid's small-radius end. The interpolant is
// linear in the node values, so each axis keeps the weights a query gives its nodes: evaluate()
// costs one pass over the nodes, with no system to solve, and stays well conditioned however
// close the nodes are.
#pragma once

#include <span>
#include <vector>

namespace stampede::kernels {

// Nodes per axis at most: a query's weights live on the stack (no allocation per evaluation).
inline constexpr int kMaxSplineNodes = 64;

// The 1-D spline's weights: s(x) = sum_k w_k(x) y_k for node values y.
class SplineWeights {
 public:
  SplineWeights() = default;
  // nodes: strictly increasing, 1 to kMaxSplineNodes of them; ok() is false otherwise.
  explicit SplineWeights(std::span<const double> nodes);
  bool ok() const { return ok_; }
  int size() const { return static_cast<int>(nodes_.size()); }
  // w[size()] = the weights at x; x outside the nodes' range extends the end intervals' cubics
  // (callers clamp).
  void at(double x, std::span<double> w) const;

 private:
  bool ok_ = false;
  std::vector<double> nodes_;
  std::vector<double> curvature_;  // size x size: the second derivatives at the nodes per unit node value
};

class TensorSpline {
 public:
  TensorSpline() = default;
  // x_nodes, y_nodes: strictly increasing; values: (x_nodes.size() * y_nodes.size()) * outputs,
  // node (i, j) at row i * y_nodes.size() + j, its outputs together. ok() is false on inconsistent
  // input.
  TensorSpline(std::span<const double> x_nodes, std::span<const double> y_nodes, std::span<const double> values,
               int outputs);
  bool ok() const { return ok_; }
  int outputs() const { return outputs_; }
  // out[outputs] = the interpolant at (x, y).
  void evaluate(double x, double y, std::span<double> out) const;

 private:
  bool ok_ = false;
  int outputs_ = 0;
  SplineWeights x_, y_;
  std::vector<double> values_;
};

}  // namespace stampede::kernels
