// The solve every galaxy fit shares, one stamp or many cutouts, amplitudes free or projected: first
// on the renderers' surrogates (where the PSFs give one) to the looser rule, then with the exact
// models from there until their own rules hold, then J^T W J at the optimum (the solver's last when
// it was taken there) and its inverse, the parameters' covariance.
#pragma once

#include "engine/fit/fit_result.hpp"
#include "engine/fit/fitter.hpp"
#include "engine/solver/levenberg_marquardt.hpp"

namespace stampede {

// A fit's least-squares problem as the solve drives it.
class SolveProblem : public LeastSquaresProblem {
 public:
  // Draw with the surrogates (true) or the exact models (false) from now on.
  virtual void use_surrogates(bool on) = 0;
  // After the surrogate pass, before the exact one: forget what the surrogate pass left (amplitudes
  // carried between trial points).
  virtual void restart() {}
  // Renders beyond the solver's evaluations since the last restart (a projected problem's).
  virtual int extra_evaluations() const { return 0; }
  // After the solve: x (the solver's vector) as the vector of every free parameter, and alpha as
  // J^T W J over all of them at x. A problem that solves some parameters linearly at each trial
  // point (the amplitudes) has fewer than the fit; false when that fails.
  virtual bool expand(LmVector* /*x*/, LmMatrix* /*alpha*/) { return true; }
};

struct SolveResult {
  LmSummary summary;  // x and alpha in the layout of every free parameter (SolveProblem::expand)
  double chi2 = NAN;  // at summary.x, in the problem's units
  LmMatrix cov;       // inverse of summary.alpha
  bool cov_ok = false;  // cov finite with a positive diagonal
};

// Solves from x0 in `units` (surrogates first when `coarse`), filling r's solver fields (stop
// reason, counts, surrogate counts, n_pixels). False when there is no fit: r->status is then
// kModelFailure (no model at the start) or kSolverFailure.
bool solve(SolveProblem& problem, LmVector x0, const FitterOptions& options, const LmUnits& units, bool coarse,
           FitResult* r, SolveResult* out);

}  // namespace stampede
