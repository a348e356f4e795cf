// Which simulated set a file belongs to, from the keys a simulation writes into its images and
// truth file alike: a GREAT08-layout set's SEED (master seed), SETIDX (set index) and NOISESD
// (noise seed), as `stampede sim` and GalSim's sets carry them, and a `sim meds` tile's SIMID (a
// digest of the simulation's options). `stampede fit` records its input's identity in the result
// header (key INSETID) and `stampede metrics` and the report refuse a truth file of another set.
#pragma once

#include <string>

#include "io/fits_file.hpp"

namespace stampede::io {

// "SEED=7 SETIDX=0 NOISESD=0" or "SIMID=0123456789abcdef" from the current HDU's keys (those
// present, in the order SEED, SETIDX, NOISESD, SIMID); "" when none is. Throws FitsError if one of
// the first three is present but not an integer.
std::string simulation_identity(FitsFile& header);

// The identity the primary header of the FITS file at `path` records (CFITSIO syntax, e.g. a
// tile-compressed ".fz"); throws FitsError when the file cannot be read.
std::string file_simulation_identity(const std::string& path);

// The result-header key of the fitted input's identity.
inline constexpr const char* kInputSetKey = "INSETID";
// The key of a `sim meds` simulation's identity, in its tiles' and truth files' primary headers.
inline constexpr const char* kSimulationIdKey = "SIMID";

}  // namespace stampede::io
