// The program's version, CMake's project version ("0.1.0"): printed by `stampede --version` and
// part of every run fingerprint, so a run is never resumed by another build of the program.
#pragma once

#include <string_view>

namespace stampede::app {

std::string_view program_version();

}  // namespace stampede::app
