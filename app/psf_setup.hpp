// The run's shared PSF from its configuration (psf_input = moffat, airy or image), for the
// commands that fit with one PSF for every object (`fit`, `calibrate build`).
#pragma once

#include <cmath>
#include <memory>
#include <string>
#include <vector>

#include "engine/render/psf_kernel.hpp"
#include "io/run_config.hpp"

namespace stampede::tools {

struct SharedPsf {
  PsfOptions options;
  std::shared_ptr<const PsfKernel> kernel;
  double e1 = NAN, e2 = NAN, fwhm = NAN;  // as written to the output rows (NaN: unknown, image PSF)
};

// Reads psf_image when psf_input = image. Throws (naming psf_input, or the image file) when the PSF
// cannot be built. Not for psf_input = moffat_catalog.
SharedPsf build_shared_psf(const io::RunConfig& cfg, const GridGeometry& geometry, FftPlanCache& plans);

// Where a PSF recorded in an input's header (io::read_psf_keys) differs from the run's analytic
// PSF: one "KEY = recorded (option = run's)" per differing parameter, in header order; empty when
// they agree to 1e-9 relative. A run with an image PSF has nothing to compare: empty.
std::vector<std::string> psf_differences(const PsfOptions& recorded, const PsfOptions& run);

}  // namespace stampede::tools
