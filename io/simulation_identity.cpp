// The simulated set's identity; see simulation_identity.hpp.
#include "io/simulation_identity.hpp"

namespace stampede::io {

std::string simulation_identity(FitsFile& header) {
  std::string id;
  auto add = [&](const char* key, const std::string& value) {
    if (!id.empty()) id += ' ';
    id.append(key).append("=").append(value);
  };
  for (const char* key : {"SEED", "SETIDX", "NOISESD"})
    if (const auto v = header.read_key_long(key)) add(key, std::to_string(*v));
  if (const auto v = header.read_key_string(kSimulationIdKey)) add(kSimulationIdKey, *v);
  return id;
}

std::string file_simulation_identity(const std::string& path) {
  FitsFile f = FitsFile::open_read(fits_root_name(path));
  f.move_to(0);
  return simulation_identity(f);
}

}  // namespace stampede::io
