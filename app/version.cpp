// The program version; STAMPEDE_VERSION is defined for this file alone by app/CMakeLists.txt.
#include "app/version.hpp"

namespace stampede::app {

std::string_view program_version() { return STAMPEDE_VERSION; }

}  // namespace stampede::app
