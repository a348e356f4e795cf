// Which simulated set a file belongs to, from the keys a GREAT08-layout set and its truth file
// both carry (`stampede sim` and GalSim's sets alike): SEED (master seed), SETIDX (set index) and
// NOISESD (noise seed). `stampede fit` records its input's identity in the result header (key
// INSETID) and `stampede metrics` refuses a truth file of another set.
#pragma once

#include <string>

#include "io/fits_file.hpp"

namespace stampede::io {

// "SEED=7 SETIDX=0 NOISESD=0" from the current HDU's keys (those present, in that order); "" when
// none is. Throws FitsError if one is present but not an integer.
std::string simulation_identity(FitsFile& header);

// The result-header key of the fitted input's identity.
inline constexpr const char* kInputSetKey = "INSETID";

}  // namespace stampede::io
