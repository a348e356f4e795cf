// The reconvolution PSF Gamma of metacalibration, with the filters it gives: a round Moffat wider
// than the PSF sheared by the step in every direction, so that Gamma~ / PSF~ stays below 1 at
// every k (MetacalFilters refuses it otherwise).
#pragma once

#include <memory>
#include <string>

#include "engine/metacal/metacal_filters.hpp"
#include "engine/metacal/metacal_options.hpp"
#include "engine/model/psf_model.hpp"

namespace stampede {

// Moffat PSF: a round Moffat of its beta and FWHM x metacal_psf_dilation (0: (1 + 2 step) x
// sqrt((1 + |e|) / (1 - |e|)), its major axis's factor). Image PSF: a round Moffat of beta 3, FWHM
// F x metacal_psf_dilation with F = 2.3548 sqrt(lambda_max) of the image's adaptive-moment
// covariance; with dilation 0, the narrowest from 0.7 F up in steps of 3 % whose filters are all
// bounded (40 tries).
// The Airy disc is refused (its transform vanishes beyond its cut-off). Null, with *error, when
// no Gamma serves; filters->reconvolution() is the Gamma chosen.
std::shared_ptr<const MetacalFilters> reconvolution_filters(const PsfModel& psf, const MetacalOptions& options,
                                                            int period, std::string* error);

}  // namespace stampede
