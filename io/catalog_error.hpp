// The error of every table a run writes (the fit catalogue, the metadetect table, a merge): I/O
// errors, unwritable paths, nothing or the wrong run to resume. The message names the file.
#pragma once

#include "engine/common/error.hpp"

namespace stampede::io {

class CatalogError : public Error {
 public:
  using Error::Error;
};

}  // namespace stampede::io
