// Reads a PSFEx model file (`*.psf`: HDU PSF_DATA, one row, column PSF_MASK; the POL* and PSF*
// keywords; ../shared/reference/survey-formats.md) into a PsfexModel. Throws FitsError naming the
// file, HDU and keyword or column for anything that is not a usable single-group model in
// X_IMAGE, Y_IMAGE.
#pragma once

#include <string>

#include "engine/model/psfex_model.hpp"

namespace stampede::io {

PsfexModel read_psfex_model(const std::string& path);

}  // namespace stampede::io
