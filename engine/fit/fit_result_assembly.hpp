// A FitResult from a solve's optimum: the one assembly of the single-stamp fit (Fitter) and the
// joint fits over cutouts and bands (ObjectFitter). Errors from the covariance, the effective
// (mirrored, softened) parameters and the component fluxes back in data units, chi2, S/N, flags
// and status. What the fits differ in is stated by the caller: the bounds checked for
// kFlagAtBound, each band's optimum and signal (an unweighted fit has none), the units, the
// renderer that gives effective values and fluxes, and the flags gathered before the solve.
#pragma once

#include <cmath>
#include <cstdint>
#include <span>

#include "engine/fit/fit_result.hpp"
#include "engine/fit/fit_units.hpp"
#include "engine/fit/multi_band_result.hpp"
#include "engine/fit/solve.hpp"
#include "engine/model/parameters.hpp"
#include "engine/render/renderer.hpp"

namespace stampede {

// One fitted band's optimum, in the fit's internal units.
struct SolvedBand {
  int band = 0;           // its index in the per-band output
  ParamVector params{};   // every parameter, with this band's amplitudes
  double signal = NAN;    // sum w m^2 of its best model over its pixels; NaN: not computed (unweighted fit)
};

// What a solve found, with what the fit that ran it says of it.
struct SolvedFit {
  const SolveResult& solved;
  std::span<const Param> free;        // the fit's free parameters: the covariance's first rows, in order
  std::span<const SolvedBand> bands;  // one per fitted band, at least one; several: amplitudes are per band
  const FitUnits& units;
  const Renderer& renderer;           // the effective values and component fluxes of a parameter vector
  double ellipticity_mirror = 0;      // |e| beyond which the model folds e (ModelOptions)
  // Bounds in data units, checked for kFlagAtBound (within 1e-6 in internal units, so the test does
  // not depend on the data's scale); null: not checked (the joint fits are unbounded).
  const ParamVector* lower = nullptr;
  const ParamVector* upper = nullptr;
  std::uint32_t flags = 0;            // gathered before the solve (masked pixels, start, unweighted)
};

// Completes *r, whose solver fields solve() filled, from `fit`. Several bands: the result's
// amplitudes and their errors are NaN, its fluxes and S/N the bands' sums, and each band's part goes
// to band_fits[band] (when band_fits is not empty; n_epochs left as it is). One band: band_fits is
// not written.
void assemble_fit_result(const SolvedFit& fit, std::span<BandFit> band_fits, FitResult* r);

}  // namespace stampede
