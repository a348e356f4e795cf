// The reconvolution PSF Gamma of metacalibration: a round Moffat wider than the PSF sheared by
// the step in every direction, so that Gamma~ / PSF~ stays below 1 at every k.
#pragma once

#include <string>

#include "engine/metacal/metacal_options.hpp"
#include "engine/model/psf_model.hpp"

namespace stampede {

// Moffat PSFs only: the Airy disc's transform vanishes beyond its cut-off (nothing to deconvolve
// there) and an image PSF has no analytic width yet. False, with *error, for those.
bool reconvolution_psf(const PsfModel& psf, const MetacalOptions& options, PsfModel* out, std::string* error);

}  // namespace stampede
