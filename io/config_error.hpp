// Every configuration problem: an unknown key, a value that does not parse, an unreadable file or
// an invalid combination. The message names the key and, where known, the file and line.
#pragma once

#include "engine/common/error.hpp"

namespace stampede::io {

class ConfigError : public Error {
 public:
  using Error::Error;
};

}  // namespace stampede::io
