// A joint fit's problem over the shape parameters alone (when projects_amplitudes(options)), each band's bulge and disc amplitudes
// solved linearly at every trial shape (variable projection, engine/solver/variable_projection.hpp,
// as the single-stamp fit's project_amplitudes). The cutouts of a band share its two amplitudes;
// the shape is every band's. chi2 at a shape is the joint fit's at the best amplitudes, so the
// optimum is the joint fit's; the solver takes no steps along the amplitudes' degeneracies, and
// the number of bands does not change the size of its problem (5 shape parameters, where the
// joint fit of B bands has 5 + 2B).
//
// normal_equations projects Kaufman's way from each band's unprojected sums: with X the shape
// columns, Phi the amplitude columns and T = G^-1 Phi^T W X, J_p^T W J_p = X^T W X - X^T W Phi T
// - T^T Phi^T W X + T^T G T and J_p^T W r = X^T W r - T^T Phi^T W r, the per-pixel projection of
// the single-stamp fit summed over cutouts. The unprojected sums also give J^T W J over every
// free parameter in the fitter's layout, for the errors.
#pragma once

#include <array>
#include <functional>
#include <span>
#include <vector>

#include "engine/fit/joint_fit_solve.hpp"
#include "engine/fit/multi_band_result.hpp"
#include "engine/solver/variable_projection.hpp"

namespace stampede {

class ProjectedJointProblem final : public SolveProblem {
 public:
  using RendererFor = JointCutouts::RendererFor;
  // kernels: the least-squares kernels of the fitter's instruction set (kernels/least_squares.hpp).
  ProjectedJointProblem(RendererFor renderer_for, const kernels::LeastSquaresKernels& kernels)
      : cutouts_(std::move(renderer_for), kernels) {}

  // The fit's cutouts (cutout c in band slot slot_of_cutout[c] < slots), the full parameter vector
  // of fixed values (data units), the free parameters (one band's list) and the fitter's index of
  // free parameter a of slot s, global(a, s), in a layout of `n_global` parameters. From here on
  // the problem is in the cutouts' units (JointCutouts::units): the solver's vector, chi2, the sums,
  // signal() and expand()'s amplitudes.
  void reset(std::span<const Observation> epochs, const ParamVector& base, std::span<const Param> free,
             std::span<const int> slot_of_cutout, int slots, const std::function<int(std::size_t, int)>& global,
             int n_global);

  int size() const { return n_shape_; }  // the solver's parameters
  int num_pixels() const override { return cutouts_.pixels(); }
  double negligible_chi2() const override { return cutouts_.negligible_chi2(); }
  bool chi2(const LmVector& x, double* chi2) override;
  bool normal_equations(const LmVector& x, double* chi2, LmMatrix* alpha, LmVector* beta) override;
  // The amplitudes found on the surrogates are not the exact model's.
  void use_surrogates(bool on) override { cutouts_.use_surrogates(on), cached_ = false, jacobian_x_ = LmVector(); }
  bool expand(LmVector* x, LmMatrix* alpha) override;

  // The solver's vector of a vector in the fitter's layout (its shape parameters).
  LmVector shape_of(const LmVector& global) const;
  // sum w m^2 of slot s's cutouts at the last normal_equations.
  double signal(int slot) const { return signal_[static_cast<std::size_t>(slot)]; }

 private:
  // The full parameter vector of slot s at shape x and amplitudes la.
  ParamVector params(const LmVector& x, const LinearAmplitudes& la) const;

  JointCutouts cutouts_;
  std::span<const Observation> epochs_;
  ParamVector base_{};
  std::span<const Param> free_;
  std::vector<int> slot_of_cutout_;
  int slots_ = 0, n_shape_ = 0, n_global_ = 0;
  std::array<int, kNumParams> shape_{};  // indices into free_ of the shape parameters
  int bulge_ = -1, disc_ = -1;           // and of the amplitudes
  std::array<std::array<int, kNumParams>, kMaxBands> global_{};
  // Each cutout's bulge and disc images (times its flux scale) at the last chi2 point.
  std::vector<double> components_;
  std::vector<std::size_t> offset_;
  std::array<LinearAmplitudes, kMaxBands> amplitudes_{}, jacobian_amplitudes_{};
  LmVector cached_x_, jacobian_x_;
  bool cached_ = false;
  LmMatrix full_alpha_;
  std::array<double, kMaxBands> signal_{};
  CutoutSums sums_;
};

}  // namespace stampede
