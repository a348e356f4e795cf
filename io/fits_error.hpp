// FitsError: the one exception type io/ throws for anything that goes wrong with a FITS file.
// Its message always names the file and HDU (and the keyword or column where relevant).
#pragma once

#include <stdexcept>

namespace stampede::io {

class FitsError : public std::runtime_error {
 public:
  using runtime_error::runtime_error;
};

}  // namespace stampede::io
