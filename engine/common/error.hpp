// stampede::Error: the base of every exception the library throws for bad input or failed I/O.
//
// FitsError (a FITS file), ConfigError (a configuration file or option) and CatalogError (the fit
// catalogue writer) derive from it, so a front end (the CLI, the Python module, the MPI driver)
// maps the library's errors to its own once, with one catch clause, and still sees each type's
// message, which names the file, key or column concerned. Programming errors (a contract broken
// by the caller, such as a span of the wrong size) stay std::invalid_argument or
// std::logic_error and are not Errors: they are bugs to fix, not conditions to report to a user.
#pragma once

#include <stdexcept>

namespace stampede {

class Error : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

}  // namespace stampede
