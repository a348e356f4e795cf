// What a joint fit over bands gives (engine/fit/object_fitter): the common shape and, per band,
// its amplitudes, fluxes and S/N. Kept apart from the fitter so output records can hold it.
#pragma once

#include <cmath>
#include <vector>

#include "engine/fit/fit_result.hpp"

namespace stampede {

// Bands in one fit: the shape's five parameters plus two amplitudes per band fit the solver.
inline constexpr int kMaxBands = 8;
static_assert(5 + 2 * kMaxBands <= kMaxFree, "the solver's storage must hold a fit of kMaxBands bands");

// One band's part of a joint fit (sky units, fluxes at the run's reference zero point).
struct BandFit {
  int n_epochs = 0;  // cutouts of this band in the fit
  double bulge_a = NAN, disc_a = NAN;  // fitted amplitudes per arcsec^2
  double bulge_flux = NAN, disc_flux = NAN, flux = NAN;
  double snr = NAN;       // sqrt(sum w m^2) over this band's cutouts
};

struct MultiBandFitResult {
  // The common shape and its errors; chi2, snr (all bands combined), iterations and flags of the
  // joint fit. Fluxes are the sums over the fitted bands; bulge_A and disc_A (params) are NaN:
  // amplitudes are per band.
  FitResult fit;
  std::vector<BandFit> bands;  // one per band, fitted or not
};

}  // namespace stampede
