// A set's shear estimate as a function of how often each unit (a ring pair, or a lone object) is
// taken: a count of 1 for every unit gives the estimate, a bootstrap draws the counts. The two sets
// of a shear pair list the same units in the same order, so one draw resamples both alike and the
// noise they share cancels in the resampled difference too.
#pragma once

#include <array>
#include <cstddef>
#include <map>
#include <span>
#include <vector>

namespace stampede {

class UnitShearEstimator {
 public:
  virtual ~UnitShearEstimator() = default;
  // Per unit, in unit order: its ring-pair label, or -1 - row for an object without one.
  virtual std::span<const long long> labels() const = 0;
  // g1, g2 from unit i taken count[i] times; NaN when no usable unit is taken.
  virtual std::array<double, 2> estimate(std::span<const int> count) const = 0;
};

// Rows to units in order of first appearance: a row's ring-pair label, or the row alone (label
// -1 - row) when it has none. What both set estimators number their units by.
class UnitLabels {
 public:
  // The unit of row `row` (pair: the labels, or empty); *added when it is a new unit.
  std::size_t unit_of(std::size_t row, std::span<const long long> pair, bool* added) {
    const std::size_t next = labels_.size();
    if (pair.empty() || pair[row] < 0) {
      labels_.push_back(-1 - static_cast<long long>(row));
      *added = true;
      return next;
    }
    const auto [it, fresh] = by_pair_.emplace(pair[row], next);
    if (fresh) labels_.push_back(pair[row]);
    *added = fresh;
    return it->second;
  }
  const std::vector<long long>& labels() const { return labels_; }

 private:
  std::map<long long, std::size_t> by_pair_;
  std::vector<long long> labels_;
};

}  // namespace stampede
