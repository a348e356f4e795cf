// The joint fits' shared solve; see joint_fit_solve.hpp.
#include "engine/fit/joint_fit_solve.hpp"

#include <algorithm>
#include <stdexcept>
#include <string>

namespace stampede {

ExactRenderer& CutoutScratch::select(ExactRenderer& r, const Observation& e, bool surrogate) {
  r.set_psf(e.psf);
  r.set_frame(e.frame);  // the surrogate follows the renderer's PSF and frame
  ExactRenderer* coarse = surrogate ? r.exact_surrogate() : nullptr;
  const std::size_t n = static_cast<std::size_t>(e.box_size) * e.box_size;
  if (model_.size() < n) {  // grows to the largest box once, then never again
    model_.resize(n);
    for (auto& j : jacobian_) j.resize(n);
  }
  model_span_ = std::span<double>(model_.data(), n);
  for (std::size_t k = 0; k < jacobian_.size(); ++k) columns_[k] = jacobian_[k].data();
  return coarse ? *coarse : r;
}

FitStatus check_cutouts(std::span<const Observation> epochs, const char* who) {
  for (const Observation& e : epochs) {
    if (!e.psf) return FitStatus::kPsfFailure;
    const std::size_t n = static_cast<std::size_t>(e.box_size) * e.box_size;
    if (e.box_size < 1 || e.pixels.size() != n || e.weight.size() != n)
      throw std::invalid_argument(std::string(who) + ": a cutout's pixels or weights are not box_size^2");
  }
  return FitStatus::kOk;
}

bool solve_joint(JointProblem& problem, LmVector x0, const FitterOptions& options, bool coarse, FitResult* r,
                 JointSolve* out) {
  LmOptions lm = options.lm;
  if (coarse) {
    LmOptions first = options.lm;
    first.eps4 = std::max(options.lm.eps4, options.surrogate_eps4);
    problem.use_surrogates(true);
    const LmSummary s = levenberg_marquardt(problem, x0, first);
    problem.use_surrogates(false);
    r->surrogate_iterations = s.iterations;
    r->surrogate_evaluations = s.evaluations;
    if (s.reason != StopReason::kInvalidStart && s.x.allFinite()) {
      x0 = s.x;
      lm.stop_at_jacobian = true;
    }
  }
  const LmSummary sum = levenberg_marquardt(problem, x0, lm);
  r->stop_reason = sum.reason;
  r->stop_value = sum.stop_value;
  r->stop_threshold = sum.stop_threshold;
  r->iterations = sum.iterations;
  r->evaluations = sum.evaluations;
  r->n_pixels = problem.num_pixels();
  if (sum.reason == StopReason::kInvalidStart) {
    r->status = FitStatus::kModelFailure;
    return false;
  }
  // J^T W J and the S/N at the optimum: the solver's last normal equations when they were there.
  out->chi2 = sum.chi2;
  LmMatrix alpha = sum.alpha;
  LmVector beta;
  if (!sum.alpha_at_x) {
    ++r->evaluations;
    if (!problem.normal_equations(sum.x, &out->chi2, &alpha, &beta)) {
      r->status = FitStatus::kSolverFailure;
      return false;
    }
  }
  out->summary = sum;
  if (!problem.expand(&out->summary.x, &alpha)) {
    r->status = FitStatus::kSolverFailure;
    return false;
  }
  out->summary.alpha = alpha;  // in the layout of summary.x
  const int n = static_cast<int>(out->summary.x.size());
  Eigen::LDLT<LmMatrix> ldlt(alpha);
  out->cov = ldlt.solve(LmMatrix::Identity(n, n));
  out->cov_ok = ldlt.info() == Eigen::Success && out->cov.allFinite() && (out->cov.diagonal().array() > 0).all();
  return true;
}

}  // namespace stampede
