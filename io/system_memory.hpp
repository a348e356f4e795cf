// The memory this machine can give a new run: MemAvailable of /proc/meminfo (Linux).
#pragma once

#include <optional>
#include <string>

namespace stampede::io {

// MemAvailable in bytes, from `meminfo` (a file in the /proc/meminfo format); nullopt when the file
// cannot be read or has no such line (another kernel or system): the caller then cannot check.
std::optional<double> available_memory_bytes(const std::string& meminfo = "/proc/meminfo");

}  // namespace stampede::io
