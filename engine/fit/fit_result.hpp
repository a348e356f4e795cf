// Per-stamp fit result: fixed size, no strings; NaN means "not computed".
#pragma once

#include <cstdint>

#include "engine/solver/levenberg_marquardt.hpp"
#include "engine/model/parameters.hpp"

namespace stampede {

enum class FitStatus : int {
  kOk = 0,             // converged by a tolerance rule: parameters usable
  kMaxIterations = 1,  // stopped at minimizer_max_iterations: best point found, use with caution
  kBadPixels = 2,      // NaN/Inf pixel or invalid weight on an unmasked pixel: nothing fitted
  kNoData = 3,         // all pixels masked or a flat stamp (every used pixel equal, zero included): nothing fitted
  kModelFailure = 4,   // no valid model at the starting point: nothing fitted
  kSolverFailure = 5,  // normal equations could not be solved: parameters not usable
  kPsfFailure = 6,     // the PSF could not be normalised: nothing fitted
};
inline constexpr int kFitStatusCount = static_cast<int>(FitStatus::kPsfFailure) + 1;  // keep: last value + 1
const char* ToString(FitStatus s);
// Whether the fitted parameters may be used for science (kMaxIterations: with a flag).
bool IsUsable(FitStatus s);
// The status of a fit the solver ended with `reason` (past a valid start); *flags gains
// kFlagNotConverged at the iteration limit.
FitStatus status_of_stop(StopReason reason, std::uint32_t* flags);

// Flag bits (documented in README, "Output flags").
enum FitFlag : std::uint32_t {
  kFlagMaskedPixels = 1u << 0,       // some pixels had zero weight
  kFlagDefaultStart = 1u << 1,       // moments failed; started from default values
  kFlagAtBound = 1u << 2,            // a free parameter ended within 1e-6 of a bound
  kFlagMirrored = 1u << 3,           // |e| ended beyond the mirror radius (effective e was folded)
  kFlagNoErrors = 1u << 4,           // J^T W J singular at the optimum: errors are NaN
  kFlagNotConverged = 1u << 5,       // max iterations reached
  kFlagUnweighted = 1u << 6,         // noise_sigma = 0 and no weight map: chi2, errors and snr in data units
};

struct FitResult {
  FitStatus status = FitStatus::kNoData;
  StopReason stop_reason = StopReason::kNone;
  double stop_value = NAN;
  double stop_threshold = NAN;
  std::uint32_t flags = 0;

  // Effective values as rendered: e after the mirror, radius after softening; fixed ones as given.
  ParamVector params;
  ParamVector errors;        // sqrt(diag((J^T W J)^-1)) for free parameters, NaN otherwise
  double e1_err = NAN, e2_err = NAN;
  double bulge_flux = NAN, disc_flux = NAN, flux = NAN;
  double chi2 = NAN;         // sum w (d - m)^2 over used pixels
  double likelihood = NAN;   // -chi2 / 2
  double snr = NAN;          // sqrt(sum w m^2) of the best model (GREAT08 matched-filter S/N)
  int n_pixels = 0;          // pixels with non-zero weight
  int iterations = 0;   // exact (final-renderer) Jacobian evaluations
  int evaluations = 0;  // exact model evaluations, Jacobian ones included
  // The same counts of the surrogate iterations before them (Renderer::surrogate; 0 without).
  int surrogate_iterations = 0;
  int surrogate_evaluations = 0;

  FitResult() {
    params.fill(NAN);
    errors.fill(NAN);
  }
};

}  // namespace stampede
