// Levenberg-Marquardt; see levenberg_marquardt.hpp.
#include "engine/solver/levenberg_marquardt.hpp"

#include <algorithm>
#include <cmath>
#include <sstream>

namespace stampede {

bool LmOptions::IsValid(std::string* why) const {
  std::ostringstream msg;
  auto check = [&](const char* name, double v, double hi) {
    if (msg.str().empty() && !(v >= 0.0 && v < hi))
      msg << name << " = " << v << ": must be in [0, " << hi << ") (0 disables the rule)";
  };
  check("levmar_eps1", eps1, INFINITY);
  check("levmar_eps2", eps2, 1.0);
  check("levmar_eps3", eps3, INFINITY);
  check("levmar_eps4", eps4, 1.0);
  if (msg.str().empty() && !(init_mu > 0.0 && init_mu < 1e10))
    msg << "levmar_LM_INIT_MU = " << init_mu << ": must be in (0, 1e10)";
  if (msg.str().empty() && !(max_iterations >= 1 && max_iterations <= 100000))
    msg << "minimizer_max_iterations = " << max_iterations << ": must be in [1, 100000]";
  if (msg.str().empty() && eps1 == 0 && eps2 == 0 && eps3 == 0 && eps4 == 0 && max_iterations > 10000)
    msg << "all levmar_eps rules are disabled and minimizer_max_iterations > 10000";
  if (msg.str().empty()) return true;
  if (why) *why = msg.str();
  return false;
}

const char* ToString(StopReason r) {
  switch (r) {
    case StopReason::kNone: return "none";
    case StopReason::kGradient: return "gradient";
    case StopReason::kRelativeStep: return "relative_step";
    case StopReason::kChi2: return "chi2";
    case StopReason::kRelativeChi2Change: return "relative_chi2_change";
    case StopReason::kNoProgress: return "no_progress";
    case StopReason::kMaxIterations: return "max_iterations";
    case StopReason::kSingular: return "singular";
    case StopReason::kInvalidStart: return "invalid_start";
  }
  return "?";
}

bool IsConverged(StopReason r) {
  switch (r) {
    case StopReason::kGradient:
    case StopReason::kRelativeStep:
    case StopReason::kChi2:
    case StopReason::kRelativeChi2Change:
    case StopReason::kNoProgress:
      return true;
    default:
      return false;
  }
}

void LmDamping::accept(double rho) {
  const double t = 2.0 * rho - 1.0;
  mu_ *= std::max(1.0 / 3.0, 1.0 - t * t * t);
  nu_ = 2.0;
}

void LmDamping::reject() {
  mu_ *= nu_;
  nu_ *= 2.0;
}

LmSummary levenberg_marquardt(LeastSquaresProblem& problem, const LmVector& x0, const LmOptions& options,
                              const LmUnits& units) {
  LmSummary s;
  const int n = static_cast<int>(x0.size());
  const LmVector unit = units.param.size() == n ? units.param : LmVector::Ones(n);
  s.x = x0;
  LmMatrix alpha(n, n);
  LmVector beta(n), step(n), trial(n), diag(n);
  double chi2 = 0;
  ++s.evaluations;
  ++s.iterations;
  if (!problem.normal_equations(s.x, &chi2, &alpha, &beta) || !std::isfinite(chi2)) {
    s.reason = StopReason::kInvalidStart;
    return s;
  }
  s.initial_chi2 = chi2;
  LmDamping damping(options.init_mu);
  const double npix = std::max(1, problem.num_pixels());
  const double negligible = problem.negligible_chi2();
  auto stop = [&](StopReason r, double value, double threshold) {
    s.reason = r;
    s.stop_value = value;
    s.stop_threshold = threshold;
  };
  bool have_jacobian = true;
  int small_steps = 0;  // consecutive accepted steps with relative chi2 change below eps4 / n
  while (true) {
    if (!have_jacobian) {
      if (s.iterations >= options.max_iterations) {
        stop(StopReason::kMaxIterations, s.iterations, options.max_iterations);
        break;
      }
      ++s.iterations;
      ++s.evaluations;
      double c = 0;
      if (!problem.normal_equations(s.x, &c, &alpha, &beta)) {  // was valid a moment ago
        stop(StopReason::kSingular, NAN, NAN);
        break;
      }
      chi2 = c;
      have_jacobian = true;
    }
    // Decrease of chi2 the undamped Gauss-Newton step would give: beta^T alpha^-1 beta.
    double gn_decrease = INFINITY;
    {
      Eigen::LDLT<LmMatrix> gn(alpha);
      if (gn.info() == Eigen::Success) {
        const LmVector d = gn.solve(beta);
        if (d.allFinite()) gn_decrease = std::abs(d.dot(beta));
      }
    }
    if (options.stop_at_jacobian && options.eps4 > 0) {
      const double scale = std::max(chi2, negligible);
      if (gn_decrease / scale < options.eps4 / npix) {
        stop(StopReason::kRelativeChi2Change, gn_decrease / scale, options.eps4 / npix);
        break;
      }
    }
    const double grad = (beta.cwiseQuotient(unit) * units.chi2_unit).cwiseAbs().maxCoeff();
    if (options.eps1 > 0 && grad <= options.eps1) {
      stop(StopReason::kGradient, grad, options.eps1);
      break;
    }
    if (options.eps3 > 0 && chi2 * units.chi2_unit <= options.eps3) {
      stop(StopReason::kChi2, chi2 * units.chi2_unit, options.eps3);
      break;
    }
    // Marquardt scaling, floored so a parameter without influence cannot make the system singular.
    // The floor compares parameters of different units, so it depends on them: engine/fit solves
    // in units where the data's scale is 1 (fit_units.hpp), else bright data floors (and all but
    // freezes) the amplitudes, whose diagonal does not grow with the data as the shape's does.
    const double dmax = alpha.diagonal().maxCoeff();
    for (int k = 0; k < n; ++k) diag[k] = std::max(alpha(k, k), 1e-12 * dmax + 1e-300);
    bool accepted = false;
    while (!accepted) {
      if (damping.saturated()) {
        stop(StopReason::kNoProgress, damping.mu(), 1e30);
        break;
      }
      LmMatrix a = alpha;
      a.diagonal() += damping.mu() * diag;
      Eigen::LDLT<LmMatrix> ldlt(a);
      step = ldlt.solve(beta);
      if (ldlt.info() != Eigen::Success || !step.allFinite()) {
        damping.reject();
        continue;
      }
      const double step_sq = step.cwiseProduct(unit).squaredNorm(), x_sq = s.x.cwiseProduct(unit).squaredNorm();
      if (options.eps2 > 0 && step_sq <= options.eps2 * options.eps2 * x_sq) {
        stop(StopReason::kRelativeStep, std::sqrt(step_sq / std::max(x_sq, 1e-300)), options.eps2);
        break;
      }
      trial = s.x + step;
      double trial_chi2 = 0;
      ++s.evaluations;
      const bool valid = problem.chi2(trial, &trial_chi2) && std::isfinite(trial_chi2);
      // Predicted decrease of chi2 for the damped step: dp^T (beta + mu D dp) (> 0).
      const double predicted = step.dot(beta + damping.mu() * diag.cwiseProduct(step));
      const double actual = chi2 - trial_chi2;
      if (valid && actual > 0.0 && predicted > 0.0) {
        damping.accept(actual / predicted);
        s.x = trial;
        const double prev = chi2;
        chi2 = trial_chi2;
        accepted = true;
        have_jacobian = false;
        if (options.eps3 > 0 && chi2 * units.chi2_unit <= options.eps3) {
          stop(StopReason::kChi2, chi2 * units.chi2_unit, options.eps3);
          break;
        }
        // Relative to chi2, or to the problem's negligible chi2 when it is below that (a model that
        // matches noise-free data to rounding keeps halving a chi2 that no longer means anything).
        const double scale = std::max(prev, negligible);
        const double rel = (prev - chi2) / scale;
        small_steps = rel < options.eps4 / npix ? small_steps + 1 : 0;
        // A heavily damped step can gain little far from the optimum: stop when the Gauss-Newton
        // model agrees that little is left to gain, or when three steps in a row gained little
        // (the model is only piecewise smooth, so near a seam the quadratic model may never agree).
        if (options.eps4 > 0 && small_steps > 0 && (gn_decrease / scale < options.eps4 / npix || small_steps >= 3)) {
          stop(StopReason::kRelativeChi2Change, rel, options.eps4 / npix);
          break;
        }
      } else {
        damping.reject();
      }
    }
    if (s.reason != StopReason::kNone) break;
  }
  s.chi2 = chi2;
  s.alpha = alpha;
  s.alpha_at_x = have_jacobian;
  return s;
}

}  // namespace stampede
