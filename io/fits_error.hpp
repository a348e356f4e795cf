// FitsError, the exception for anything that goes wrong with a FITS file, and the one helper
// that turns a CFITSIO status into text for such messages.
//
// FitsFile's messages always name the file and HDU (and the keyword or column where relevant).
// io/ also throws ConfigError (config_error.hpp) and CatalogError (catalog_writer.hpp); all three
// derive from stampede::Error (engine/common/error.hpp).
#pragma once

#include <string>

#include "engine/common/error.hpp"

namespace stampede::io {

class FitsError : public Error {
 public:
  using Error::Error;
};

// CFITSIO's short text for `status`, e.g. "could not open the named file (CFITSIO status 104)".
// Also empties CFITSIO's global error-message stack, which would otherwise keep growing (and leak
// stale messages into later reports).
std::string cfitsio_status_text(int status);

}  // namespace stampede::io
