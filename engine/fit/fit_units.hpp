// The units one fit works in: the data (one stamp, or every cutout of an object in a joint fit) and
// its weights divided by powers of two near their largest values, so the start, the solver and every
// tolerance see the same numbers whatever the data's scale (ADU, nanomaggies, electrons). Powers of
// two make the change of units exact.
#pragma once

#include <cmath>

#include "engine/model/parameters.hpp"

namespace stampede {

struct FitUnits {
  double data = 1.0;    // data units per internal unit, for the pixels and the amplitudes
  double weight = 1.0;  // weight units per internal unit

  // The units of data whose largest |pixel| and largest weight over the used pixels are given
  // (either not positive and finite: that unit stays 1).
  static FitUnits for_data(double max_abs_pixel, double max_weight);

  // chi2 (in data units) per internal unit of chi2.
  double chi2() const { return weight * data * data; }
  // Data units per internal unit of parameter p: the amplitudes carry the data's unit; positions,
  // radii, ellipticities and indices are the same in both.
  double of(Param p) const { return p == Param::kBulgeA || p == Param::kDiscA ? data : 1.0; }
  ParamVector to_internal(const ParamVector& p) const;
  ParamVector to_data(const ParamVector& p) const;
  // The error of p in data units from its variance in internal units (a diagonal entry of the
  // inverse of J^T W J, whose chi2 is chi2() times smaller).
  double error(Param p, double internal_variance) const { return of(p) * std::sqrt(internal_variance / chi2()); }
};

}  // namespace stampede
