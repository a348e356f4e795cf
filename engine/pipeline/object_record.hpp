// One output row: what the engine knows about one input object after fitting it.
//
// The per-exposure inputs (cutout, weight, PSF, pixel-to-sky Jacobian) belong to the batch that
// carries the object to the fitter, not to this record: however many cutouts an object has, its row
// holds one joint fit. What survey (MEDS) input adds per object -- the sky identity, how many
// cutouts were fitted and how masked they were, the bands' fluxes -- is in `survey`
// (survey_record.hpp), and the fit is then in sky units; grid and catalogue rows leave it at its
// defaults.
#pragma once

#include <cmath>
#include <cstdint>

#include "engine/fit/fit_result.hpp"
#include "engine/metacal/metacal_record.hpp"
#include "engine/pipeline/survey_record.hpp"

namespace stampede {

// Input-side flag bits, merged into the row's `flags` above the fit's own bits (fit_result.hpp).
enum InputFlag : std::uint32_t {
  kFlagEdge = 1u << 16,          // the stamp reaches beyond the image; outside pixels masked
  kFlagPsfFailure = 1u << 17,    // the object's PSF could not be built
  kFlagMetacalFailure = 1u << 18,  // metacal: pixels masked, or a sheared image's fit not ok: R unusable
  kFlagNoUsableEpoch = 1u << 19,   // survey input: no cutout could be used (all masked, bad, or without a PSF)
  kFlagTooMasked = 1u << 20,       // survey input: the unmasked fraction fell below min_unmasked_fraction
  kFlagBadZeroPoint = 1u << 21,    // survey input: a cutout dropped, its image's magzp not a usable zero point
  // Multi-band input: a band had no usable cutout (all masked, bad or without a PSF) or too few
  // unmasked pixels, and the shape was fitted without it (its columns NaN, n_epochs_<band> 0). Not
  // shear-excluding: the other bands measured the shape, and metacal's R is that fit's.
  kFlagBandLeftOut = 1u << 22,
  // Survey input: a cutout dropped because its PSF could not be built (a missing or broken PSFEx
  // file), the object fitted on its other cutouts. Not shear-excluding: the shape is the other
  // epochs' fit. An object left with no cutout is flagged kFlagNoUsableEpoch and kFlagPsfFailure.
  kFlagPsfCutoutDropped = 1u << 23,
};

// Rows whose ellipticity may enter a shear estimate (`stampede metrics`, the noise-bias
// calibration): status ok and none of the flags that make e doubtful.
constexpr std::uint32_t kShearExcludingFlags =
    kFlagAtBound | kFlagNoErrors | kFlagNotConverged | kFlagEdge | kFlagPsfFailure | kFlagMetacalFailure |
    kFlagNoUsableEpoch | kFlagTooMasked;
inline bool usable_for_shear(FitStatus status, std::uint32_t flags) {
  return status == FitStatus::kOk && !(flags & kShearExcludingFlags);
}

struct ObjectRecord {
  std::int64_t id = -1;        // grid: iy * nx + ix; catalogue: the catalogue's id
  std::int32_t ix = -1, iy = -1;            // grid position (-1 for catalogue input)
  double x_image = NAN, y_image = NAN;      // catalogue position, FITS 1-based pixels (NaN for grid)
  double stamp_x0 = 0, stamp_y0 = 0;        // 0-based image coordinate of the stamp's pixel (0, 0)
  FitResult fit;
  std::uint32_t flags = 0;     // fit.flags | input flags
  double time_us = NAN;        // wall time of this object's fit, microseconds
  double psf_e1 = NAN, psf_e2 = NAN, psf_fwhm = NAN;
  MetacalRecord metacal;       // metacal runs only (fit is then the noshear image's)
  SurveyRecord survey;         // survey (MEDS) input only
};

}  // namespace stampede
