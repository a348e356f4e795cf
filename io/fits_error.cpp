// The CFITSIO status text of io/'s error messages; see fits_error.hpp.
#include "io/fits_error.hpp"

#include <fitsio.h>

namespace stampede::io {

std::string cfitsio_status_text(int status) {
  char text[FLEN_STATUS] = {};
  fits_get_errstatus(status, text);
  fits_clear_errmsg();
  return std::string(text) + " (CFITSIO status " + std::to_string(status) + ")";
}

}  // namespace stampede::io
