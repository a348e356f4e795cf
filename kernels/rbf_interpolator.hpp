// Gaussian radial-basis-function interpolation of scattered data in d dimensions (the
// noise-bias calibration's interpolation of bias coefficients between grid points, im3shape
// section 5.3): f(x) = sum_i w_i exp(-|S (x - x_i)|^2 / 2) + c_0 + sum_k c_k x_k, with
// S = diag(1 / length_k); the weights solve the interpolation conditions f(x_i) = y_i exactly
// with sum_i w_i = sum_i w_i x_ik = 0 (the usual polynomial augmentation: a plane is reproduced
// exactly, and far from the nodes f tends to the plane rather than to zero).
#pragma once

#include <span>
#include <vector>

namespace stampede::kernels {

class RbfInterpolator {
 public:
  RbfInterpolator() = default;
  // nodes: n points of `dims` coordinates each (row-major, n * dims); values: n * outputs
  // (row-major: node i's outputs together); length: the Gaussian width per dimension (> 0).
  // ok() is false when the system is singular (repeated nodes) or the input is inconsistent.
  RbfInterpolator(std::span<const double> nodes, int dims, std::span<const double> values, int outputs,
                  std::span<const double> length);
  bool ok() const { return ok_; }
  int outputs() const { return outputs_; }
  // out[outputs] = f(x), x of `dims` coordinates.
  void evaluate(std::span<const double> x, std::span<double> out) const;

 private:
  bool ok_ = false;
  int dims_ = 0, outputs_ = 0, n_ = 0;
  std::vector<double> nodes_, inv_length_, weights_;  // weights_: (n + dims + 1) * outputs
  double basis(std::span<const double> x, int node) const;
};

}  // namespace stampede::kernels
