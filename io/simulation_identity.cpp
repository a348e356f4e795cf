// The simulated set's identity; see simulation_identity.hpp.
#include "io/simulation_identity.hpp"

namespace stampede::io {

std::string simulation_identity(FitsFile& header) {
  std::string id;
  for (const char* key : {"SEED", "SETIDX", "NOISESD"})
    if (const auto v = header.read_key_long(key)) {
      if (!id.empty()) id += ' ';
      id.append(key).append("=").append(std::to_string(*v));
    }
  return id;
}

}  // namespace stampede::io
