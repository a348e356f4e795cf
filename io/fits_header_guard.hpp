// A scan of a FITS file's headers, before CFITSIO parses them, for cards that crash the CFITSIO
// Debian 12 ships (4.2.0): an unquoted TTYPEn value of 70 characters overflows CFITSIO's 70-byte
// column name by one (strcpy in ffgtbp; glibc aborts the process). Found by fuzz_catalogue.
#pragma once

#include <string>

namespace stampede::io {

// Walks the headers of the file `root` (a path on disk, no CFITSIO syntax; plain or
// gzip-compressed, as CFITSIO reads both) HDU by HDU; throws FitsError naming the file, HDU and
// card for a TTYPEn whose value is not a quoted string (the standard requires one), and for an
// HDU whose data runs past the end of the file (readers size buffers from the header). Files it
// cannot walk (not FITS, a header without END) are left to CFITSIO, which reports them.
void check_fits_headers(const std::string& root);

}  // namespace stampede::io
