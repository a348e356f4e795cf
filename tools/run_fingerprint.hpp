// The fingerprint a resumable command writes beside its partial output: 16 hex digits of the
// FNV-1a hash of everything that identifies the run (input, options), so `--resume` refuses the
// leftovers of another run.
#pragma once

#include <cstdint>
#include <cstdio>
#include <string>

namespace stampede::tools {

inline std::string run_fingerprint(const std::string& identity) {
  std::uint64_t h = 1469598103934665603ull;
  for (unsigned char c : identity) h = (h ^ c) * 1099511628211ull;
  char hex[17];
  std::snprintf(hex, sizeof hex, "%016llx", static_cast<unsigned long long>(h));
  return hex;
}

}  // namespace stampede::tools
