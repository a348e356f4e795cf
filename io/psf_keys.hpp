// The PSF of a simulated set or of a calibration as header keywords: PSFTYPE = 'moffat' with
// PSFBETA PSFFWHM PSFE1 PSFE2 PSFTRUNC, or 'airy' with PSFLOD PSFOBSC. Lengths in pixels,
// ellipticities as reduced shear (a - b) / (a + b).
#pragma once

#include <optional>

#include "engine/model/psf_model.hpp"
#include "io/fits_file.hpp"

namespace stampede::io {

// Into the current HDU. Analytic PSFs only (an image PSF has no keywords: throws).
void write_psf_keys(FitsFile& f, const PsfModel& psf);
// From the current HDU; without PSFTYPE a Moffat (GalSim's sets), PSFTRUNC and PSFOBSC default to 0.
// Throws FitsError naming the file and the missing or bad keyword.
PsfModel read_psf_keys(FitsFile& f);
// The same where the HDU records a PSF at all (PSFTYPE, PSFBETA or PSFLOD present); nullopt otherwise.
std::optional<PsfModel> read_psf_keys_if_present(FitsFile& f);

}  // namespace stampede::io
