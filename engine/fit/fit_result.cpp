// FitStatus names; see fit_result.hpp.
#include "engine/fit/fit_result.hpp"

namespace stampede {

const char* ToString(FitStatus s) {
  switch (s) {
    case FitStatus::kOk: return "ok";
    case FitStatus::kMaxIterations: return "max_iterations";
    case FitStatus::kBadPixels: return "bad_pixels";
    case FitStatus::kNoData: return "no_data";
    case FitStatus::kModelFailure: return "model_failure";
    case FitStatus::kSolverFailure: return "solver_failure";
    case FitStatus::kPsfFailure: return "psf_failure";
  }
  return "?";
}

bool IsUsable(FitStatus s) { return s == FitStatus::kOk || s == FitStatus::kMaxIterations; }

FitStatus status_of_stop(StopReason reason, std::uint32_t* flags) {
  switch (reason) {
    case StopReason::kMaxIterations:
      *flags |= kFlagNotConverged;
      return FitStatus::kMaxIterations;
    case StopReason::kSingular: return FitStatus::kSolverFailure;
    default: return FitStatus::kOk;
  }
}

}  // namespace stampede
