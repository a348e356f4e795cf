// What a survey object's row adds to a grid row: its identity on the sky and how its multi-epoch
// fit went (a MEDS tile's objects, `stampede fit --meds`). The fit itself (ObjectRecord::fit) is
// then in sky units: e in the (u, v) frame, x0 y0 and radius in arcsec, fluxes at the run's
// reference zero point.
#pragma once

#include <array>
#include <cmath>
#include <cstdint>

#include "engine/fit/multi_band_result.hpp"

namespace stampede {

struct SurveyRecord {
  std::int64_t number = -1;        // the object's label in the seg map
  double ra = NAN, dec = NAN;      // degrees
  std::int32_t n_epochs = 0;       // cutouts fitted
  double masked_fraction = NAN;    // of the usable cutouts' pixels
  double psf_size = NAN;           // mean over the fitted cutouts of sqrt((Ixx + Iyy) / 2), pixels
  std::int32_t is_bulge = -1;      // bord: 1 the pure bulge won, 0 the pure disc; bd: -1
  double other_likelihood = NAN;   // bord: the losing model's log-likelihood; bd: NaN
  double gamma_fwhm = NAN;         // metacal runs: the reconvolution PSF's FWHM on the sky, arcsec
  // Multi-band runs: each band's cutouts, fluxes and S/N (in the order of the run's bands; the fit
  // is then the common shape, its fluxes summed over bands).
  std::array<BandFit, kMaxBands> bands{};
};

}  // namespace stampede
