// Levenberg-Marquardt for small dense non-linear least squares, allocation-free per solve.
//
// Algorithm: K. Madsen, H. B. Nielsen, O. Tingleff, "Methods for non-linear least squares
// problems" (2004), algorithm 3.16, as implemented in levmar (which im3shape used), with
// Marquardt's scaling D = diag(J^T W J) so the damping is invariant to parameter units (bulge
// amplitudes are ~1e5 while centroids are ~1). Stopping rules are the paper's appendix B:
//   eps1: max_k |beta_k| <= eps1, beta = J^T W (d - m) = -(1/2) d chi2 / dp     (0 disables)
//   eps2: |dp|^2 <= eps2^2 |p|^2 for the proposed step                          (0 disables)
//   eps3: chi2 <= eps3                                                          (0 disables)
//   eps4: |chi2_prev - chi2| / max(chi2_prev, negligible_chi2) < eps4 / n_pixels after an accepted step, and either the
//         undamped Gauss-Newton step predicts no more than that, or it is the third such step in a
//         row (0 disables)
//         (with stop_at_jacobian, also when a Jacobian point's Gauss-Newton step predicts no more)
//   max_iterations: Jacobian evaluations.
// A step to parameters where no model exists is rejected like an uphill step (the paper's
// "chi2 = 2 per pixel" convention would be accepted by an unweighted fit of bright data).
#pragma once

#include <Eigen/Dense>
#include <string>

namespace stampede {

// The solver knows nothing of the galaxy model: it sizes its fixed storage for up to 24 free
// parameters (the model has 12; a multi-band fit has the shape plus two amplitudes per band, up to
// eight bands; engine/fit asserts that they fit).
inline constexpr int kMaxFree = 24;
using LmVector = Eigen::Matrix<double, Eigen::Dynamic, 1, 0, kMaxFree, 1>;
using LmMatrix = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, 0, kMaxFree, kMaxFree>;

struct LmOptions {
  double eps1 = 0.0;            // levmar_eps1: gradient threshold (chi2 per parameter unit); 0 = off
  // eps2 is off by default: |p| is dominated by the bulge amplitude (~1e5), so a relative step
  // rule stops fits whose ellipticity is still moving (the paper's warning about scaling).
  double eps2 = 0.0;            // levmar_eps2: relative step size; 0 = off
  double eps3 = 0.0;            // levmar_eps3: absolute chi2; 0 = off
  double eps4 = 1e-6;           // levmar_eps4: relative chi2 change per pixel; 0 = off
  double init_mu = 1e-3;        // levmar_LM_INIT_MU: initial damping relative to diag(J^T W J)
  int max_iterations = 200;     // minimizer_max_iterations
  // eps4 also holds at a Jacobian point whose undamped Gauss-Newton step predicts a chi2 decrease
  // below eps4 / n_pixels of chi2 (no step is then taken): for a solve that starts next to its
  // optimum, e.g. the exact iterations after a surrogate's (engine/fit/fitter.hpp).
  bool stop_at_jacobian = false;

  bool IsValid(std::string* why) const;
};

// Why a solve ended. Each value says what the caller may do with the parameters.
enum class StopReason {
  kNone = 0,            // not run
  kGradient,            // eps1: converged
  kRelativeStep,        // eps2: converged
  kChi2,                // eps3: converged
  kRelativeChi2Change,  // eps4: converged
  kNoProgress,          // damping saturated: no downhill step exists at machine precision; converged
  kMaxIterations,       // best point so far; may not be converged
  kSingular,            // normal equations could not be solved: not usable
  kInvalidStart,        // no model at the starting point: not usable
};
const char* ToString(StopReason r);
// Converged by one of the tolerance rules.
bool IsConverged(StopReason r);

// The problem the solver drives. The model is evaluated at full parameter vectors by the problem.
class LeastSquaresProblem {
 public:
  virtual ~LeastSquaresProblem() = default;
  virtual int num_pixels() const = 0;
  // chi2 at x; false when no model exists there.
  virtual bool chi2(const LmVector& x, double* chi2) = 0;
  // chi2, alpha = J^T W J and beta = J^T W (d - m) at x; false when no model exists there.
  virtual bool normal_equations(const LmVector& x, double* chi2, LmMatrix* alpha, LmVector* beta) = 0;
  // A chi2 at which the fit is exact to rounding (e.g. a tiny fraction of the data's own
  // sum w d^2): eps4 then measures chi2 changes against it rather than against chi2 itself. 0: none.
  virtual double negligible_chi2() const { return 0.0; }
};

// Damping schedule (Nielsen): accepted step with gain ratio rho: mu *= max(1/3, 1 - (2 rho - 1)^3),
// nu = 2; rejected: mu *= nu, nu *= 2.
class LmDamping {
 public:
  explicit LmDamping(double mu0) : mu_(mu0) {}
  double mu() const { return mu_; }
  double nu() const { return nu_; }
  void accept(double rho);
  void reject();
  bool saturated() const { return !(mu_ < 1e30); }

 private:
  double mu_;
  double nu_ = 2.0;
};

// The units the tolerances are stated in when the problem is solved in rescaled ones:
// x_stated[k] = param[k] * x[k] and chi2_stated = chi2_unit * chi2. eps1, eps2 and eps3 are
// absolute, so they are tested (and their values reported) in the stated units; eps4 and the
// damping are relative and need none.
struct LmUnits {
  double chi2_unit = 1.0;
  LmVector param;  // empty: every parameter in the stated units
};

struct LmSummary {
  LmVector x;               // best parameters
  double chi2 = NAN;
  double initial_chi2 = NAN;
  LmMatrix alpha;           // J^T W J at x (for parameter errors)
  bool alpha_at_x = false;  // alpha was evaluated at the final x
  int iterations = 0;       // Jacobian evaluations
  int evaluations = 0;      // model evaluations, Jacobian ones included
  StopReason reason = StopReason::kNone;
  double stop_value = NAN;      // the tested quantity of the rule that fired
  double stop_threshold = NAN;  // and its threshold
};

LmSummary levenberg_marquardt(LeastSquaresProblem& problem, const LmVector& x0, const LmOptions& options,
                              const LmUnits& units = {});

}  // namespace stampede
