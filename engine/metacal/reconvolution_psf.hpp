// The reconvolution PSF Gamma of metacalibration, with the filters it gives, by the options' rule
// (MetacalOptions::reconvolution): a round Gaussian (the PSF's adaptive Gaussian dilated, as the
// reference metadetect package's "fitgauss") or a round Moffat, wider than the PSF sheared by the
// step in every direction, so that Gamma~ / PSF~ stays below 1 at every k (MetacalFilters refuses
// it otherwise). A Gaussian Gamma falls faster than any PSF with a Moffat-like or Gaussian core, so
// it is bounded without the widening a Moffat Gamma needs over a Gaussian PSF (docs/metacal.md).
#pragma once

#include <memory>
#include <span>
#include <string>
#include <vector>

#include "engine/metacal/metacal_filters.hpp"
#include "engine/metacal/metacal_options.hpp"
#include "engine/model/pixel_frame.hpp"
#include "engine/model/psf_model.hpp"

namespace stampede {

// The Gaussian rule: a round Gaussian of variance ((1 + 2 step) sigma_major)^2 - 1/12,
// sigma_major^2 the major axis's variance of the PSF x pixel's adaptive moments (psf_dilation > 0
// replaces 1 + 2 step): Gamma x pixel, the metacal images' PSF, is the dilated fit. kGauss accepts
// filters up to a gain of 1.5; kAuto takes it where they stay <= 1.01 (as the Moffat rule's), else
// the Moffat rule.
// The Moffat rule: Moffat PSF: a round Moffat of its beta and FWHM x metacal_psf_dilation (0: (1 +
// 2 step) x sqrt((1 + |e|) / (1 - |e|)), its major axis's factor). Image PSF: a round Moffat of beta 3, FWHM
// F x metacal_psf_dilation with F = 2.3548 sqrt(lambda_max) of the image's adaptive-moment
// covariance; with dilation 0, the narrowest from 0.5 F up in steps of 3 % whose filters are all
// bounded (40 rungs, searched by bisection on the filters' coarse check).
// The Airy disc is refused (its transform vanishes beyond its cut-off). Null, with *error, when
// no Gamma serves; filters->reconvolution() is the Gamma chosen.
std::shared_ptr<const MetacalFilters> reconvolution_filters(const PsfModel& psf, const MetacalOptions& options,
                                                            int period, std::string* error);

}  // namespace stampede

namespace stampede {

// A round Moffat on the sky (FWHM in the frame's sky units) as the profile it is in the frame's
// pixels: FWHM / sqrt|det J|, its ellipse J^T J's. The identity frame gives the round Moffat.
PsfModel round_on_sky(double beta, double fwhm, const PixelFrame& frame);

// One cutout's PSF (in its pixels), its frame and its metacal grid's period.
struct MetacalEpochPsf {
  const PsfModel* psf = nullptr;
  PixelFrame frame;
  int period = 0;
};

// The one Gamma of a multi-epoch object: round on the sky, the filters of every cutout.
struct SkyReconvolution {
  PsfKind kind = PsfKind::kMoffat;  // kGaussian or kMoffat
  double fwhm = 0, beta = 3;  // on the sky, in the frames' units (arcsec); beta: a Moffat's
  std::vector<std::shared_ptr<const MetacalFilters>> filters;  // per cutout: Gamma in its pixels
};

// The Gaussian rule: each cutout's Gaussian Gamma on the sky by the single-stamp rule (the pixel's
// variance |det J| / 12 on the sky), the widest of them for every cutout. The Moffat rule: each
// cutout's start by the single-stamp rule above, carried to the sky: a Moffat PSF's
// FWHM x dilation x s_k (s_k the largest singular value of J_k: the widest a round pixel Gamma is
// on the sky), of its beta; an image PSF's 0.5 (or metacal_psf_dilation) x the Gaussian-equivalent
// FWHM of its covariance on the sky's major axis (J C J^T), beta 3. Gamma starts at the largest
// start, and is widened by 3 % (up to 40 rungs) until every cutout's filters are bounded. One
// cutout with a unit Jacobian gets the single-stamp Gamma exactly. False, with *error naming the
// cutout (0-based in `epochs`), when none serves.
bool sky_reconvolution(std::span<const MetacalEpochPsf> epochs, const MetacalOptions& options, SkyReconvolution* out,
                       std::string* error);

}  // namespace stampede
