// Fit units; see fit_units.hpp.
#include "engine/fit/fit_units.hpp"

#include <cmath>

namespace stampede {

namespace {

// The power of two at or below v (in [v/2, v]), or 1 when v is not positive and finite.
double power_of_two_below(double v) { return v > 0.0 && std::isfinite(v) ? std::ldexp(1.0, std::ilogb(v)) : 1.0; }

}  // namespace

FitUnits FitUnits::for_data(double max_abs_pixel, double max_weight) {
  return FitUnits{power_of_two_below(max_abs_pixel), power_of_two_below(max_weight)};
}

ParamVector FitUnits::to_internal(const ParamVector& p) const {
  ParamVector q = p;
  for (int k = 0; k < kNumParams; ++k) q[k] /= of(static_cast<Param>(k));
  return q;
}

ParamVector FitUnits::to_data(const ParamVector& p) const {
  ParamVector q = p;
  for (int k = 0; k < kNumParams; ++k) q[k] *= of(static_cast<Param>(k));
  return q;
}

}  // namespace stampede
