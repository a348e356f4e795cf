// MemAvailable from /proc/meminfo; see system_memory.hpp.
#include "io/system_memory.hpp"

#include <fstream>
#include <sstream>

namespace stampede::io {

std::optional<double> available_memory_bytes(const std::string& meminfo) {
  std::ifstream in(meminfo);
  std::string line;
  while (std::getline(in, line)) {
    if (!line.starts_with("MemAvailable:")) continue;
    std::istringstream fields(line.substr(13));
    double kib = 0;
    std::string unit;
    if (fields >> kib >> unit && unit == "kB" && kib >= 0) return kib * 1024.0;
    return std::nullopt;
  }
  return std::nullopt;
}

}  // namespace stampede::io
