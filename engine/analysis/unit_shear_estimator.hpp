// A set's shear estimate as a function of how often each unit (a ring pair, or a lone object) is
// taken: a count of 1 for every unit gives the estimate, a bootstrap draws the counts. The two sets
// of a shear pair list the same units in the same order, so one draw resamples both alike and the
// noise they share cancels in the resampled difference too.
#pragma once

#include <array>
#include <span>

namespace stampede {

class UnitShearEstimator {
 public:
  virtual ~UnitShearEstimator() = default;
  // Per unit, in unit order: its ring-pair label, or -1 - row for an object without one.
  virtual std::span<const long long> labels() const = 0;
  // g1, g2 from unit i taken count[i] times; NaN when no usable unit is taken.
  virtual std::array<double, 2> estimate(std::span<const int> count) const = 0;
};

}  // namespace stampede
