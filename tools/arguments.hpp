// Command-line helpers shared by the sub-commands.
#pragma once

#include <stdexcept>
#include <string>

namespace stampede::tools {

// The value after option argv[*i] (advancing *i); a clear error when it is missing.
inline std::string option_value(int argc, char** argv, int* i) {
  if (*i + 1 >= argc) throw std::invalid_argument(std::string("option ") + argv[*i] + " needs a value");
  return argv[++*i];
}

}  // namespace stampede::tools
