// What the joint fits over cutouts (MultiEpochFitter) and over bands (MultiBandFitter) share: the
// scratch a cutout is drawn into, the check of their cutouts, and the solve itself, as the
// single-stamp fit's: first on the cutouts' surrogates (where their PSFs have one) to the looser
// rule, then exactly from there until the exact model's own rules hold, then J^T W J at the
// optimum (the solver's last when it was there) and its inverse.
#pragma once

#include <array>
#include <span>
#include <vector>

#include "engine/fit/fit_result.hpp"
#include "engine/fit/fitter.hpp"
#include "engine/fit/multi_epoch_fitter.hpp"

namespace stampede {

// A joint fit's problem: it draws with each cutout renderer's surrogate while asked to.
class JointProblem : public LeastSquaresProblem {
 public:
  virtual void use_surrogates(bool on) = 0;
  // After the solve: x (the solver's vector) as the fitter's vector of every free parameter, and
  // alpha as J^T W J over all of them at x. A problem that solves some parameters linearly at each
  // trial point (ProjectedJointProblem) has fewer than the fit; here both stay as they are.
  virtual bool expand(LmVector* /*x*/, LmMatrix* /*alpha*/) { return true; }
};

// A cutout's model and derivative images, grown to the largest box once and then reused.
class CutoutScratch {
 public:
  // `r` set to e's PSF and frame, the scratch sized for e; returns the renderer to draw with (r's
  // exact surrogate when `surrogate` and r has one).
  ExactRenderer& select(ExactRenderer& r, const Observation& e, bool surrogate);
  std::span<double> model() const { return model_span_; }
  const std::vector<double>& derivative(std::size_t k) const { return jacobian_[k]; }
  std::span<double* const> columns(std::size_t n) const { return {columns_.data(), n}; }

 private:
  std::vector<double> model_;
  std::span<double> model_span_;
  std::array<std::vector<double>, kNumParams> jacobian_;
  std::array<double*, kNumParams> columns_{};
};

// kPsfFailure when a cutout has no PSF (else kOk); throws std::invalid_argument naming `who` when a
// cutout's pixels or weights are not box_size^2.
FitStatus check_cutouts(std::span<const Observation> epochs, const char* who);

// Whether any cutout's PSF gives its renderer (renderer_for(box_size)) an exact surrogate: the
// solve then starts on the surrogates.
template <class RendererFor>
bool any_surrogate(std::span<const Observation> epochs, RendererFor&& renderer_for) {
  bool coarse = false;
  for (const Observation& e : epochs) {
    ExactRenderer& r = renderer_for(e.box_size);
    r.set_psf(e.psf);
    coarse = coarse || r.exact_surrogate() != nullptr;
  }
  return coarse;
}

struct JointSolve {
  LmSummary summary;
  double chi2 = NAN;
  LmMatrix cov;
  bool cov_ok = false;
};

// Solves from x0 (the solver's vector; surrogates first when `coarse`), filling r's solver fields
// (stop reason, counts, n_pixels). out->summary.x and out->cov are in the fitter's layout
// (JointProblem::expand). False when there is no fit: r->status is then kModelFailure or
// kSolverFailure.
bool solve_joint(JointProblem& problem, LmVector x0, const FitterOptions& options, bool coarse, FitResult* r,
                 JointSolve* out);

}  // namespace stampede
