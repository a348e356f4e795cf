// Shear pairs (`stampede sim great08 --shear-pairs`): two sets of the same galaxies and the same
// noise, sheared by +g and -g. Half the difference of their estimates is (1 + m) g with everything
// the two share (shape noise, pixel noise, noise bias even in g) cancelling; half the sum is c.
// So m is measured from a few sets to a precision independent sets would need hundreds for
// (Sheldon & Huff 2017, section 5). Errors: a bootstrap that draws one set of unit counts for both.
#pragma once

#include <cstdint>
#include <vector>

#include "engine/analysis/shear_metrics.hpp"
#include "engine/analysis/unit_shear_estimator.hpp"

namespace stampede {

struct ShearPairEstimate {
  double g1_true = 0, g2_true = 0;  // the + set's shear
  std::array<double, 2> half_difference{}, half_difference_err{};  // (g_+ - g_-) / 2: (1 + m) g
  std::array<double, 2> half_sum{}, half_sum_err{};                // (g_+ + g_-) / 2: c
};

// plus, minus: the two sets' estimators, listing the same units (else std::invalid_argument).
ShearPairEstimate estimate_shear_pair(const UnitShearEstimator& plus, const UnitShearEstimator& minus,
                                      double g1_true, double g2_true, int bootstrap, std::uint64_t seed);

struct ShearPairMetrics {
  BiasFit component[2];            // m from half differences (a line through 0), c from half sums
  double c_plus = 0, c_cross = 0;  // c in the PSF frame
};

// Weighted by the bootstrap errors (all zero: unweighted, errors from the scatter).
ShearPairMetrics combine_shear_pairs(const std::vector<ShearPairEstimate>& pairs, double psf_e1, double psf_e2);

}  // namespace stampede
