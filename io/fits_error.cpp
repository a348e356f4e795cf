// The CFITSIO status text of io/'s error messages; see fits_error.hpp.
#include "io/fits_error.hpp"

#include <fitsio.h>

#include <cerrno>
#include <system_error>

#include "io/durable_file.hpp"

namespace stampede::io {

std::string cfitsio_status_text(int status) {
  const int error = errno;  // a failed write's, left by CFITSIO's file driver
  char text[FLEN_STATUS] = {};
  fits_get_errstatus(status, text);
  fits_clear_errmsg();
  std::string out = std::string(text) + " (CFITSIO status " + std::to_string(status) + ")";
  // "couldn't write to file" names neither a full disk nor a file-size limit: the system's reason does.
  if (status == WRITE_ERROR && (error == ENOSPC || error == EFBIG || error == EDQUOT)) {
    const std::string limit = error == EFBIG ? space_exhausted_reason("", EFBIG) : "";
    out += ": " + std::generic_category().message(error) + (limit.empty() ? "" : " (" + limit + ")");
  }
  return out;
}

}  // namespace stampede::io
