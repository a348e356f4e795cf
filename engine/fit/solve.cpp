// The fits' one solve; see solve.hpp.
#include "engine/fit/solve.hpp"

#include <algorithm>
#include <cmath>

namespace stampede {

bool solve(SolveProblem& problem, LmVector x0, const FitterOptions& options, const LmUnits& units, bool coarse,
           FitResult* r, SolveResult* out) {
  LmOptions lm = options.lm;
  if (coarse) {
    // The surrogates' optimum, to the looser rule, is where the exact iterations start: near
    // enough that they take one or two Jacobians (the surrogate's model error sets how far).
    LmOptions first = options.lm;
    first.eps4 = std::max(options.lm.eps4, options.surrogate_eps4);
    problem.use_surrogates(true);
    const LmSummary s = levenberg_marquardt(problem, x0, first, units);
    problem.use_surrogates(false);
    r->surrogate_iterations = s.iterations;
    r->surrogate_evaluations = s.evaluations + problem.extra_evaluations();
    problem.restart();
    if (s.reason != StopReason::kInvalidStart && s.x.allFinite()) {
      x0 = s.x;
      lm.stop_at_jacobian = true;
    }
  }
  const LmSummary sum = levenberg_marquardt(problem, x0, lm, units);
  r->stop_reason = sum.reason;
  r->stop_value = sum.stop_value;
  r->stop_threshold = sum.stop_threshold;
  r->iterations = sum.iterations;
  r->evaluations = sum.evaluations;
  r->n_pixels = problem.num_pixels();
  if (sum.reason == StopReason::kInvalidStart) {  // no model, so no chi2: it stays NaN
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
  r->evaluations += problem.extra_evaluations();
  out->summary = sum;
  if (!problem.expand(&out->summary.x, &alpha) || !std::isfinite(out->chi2)) {
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
