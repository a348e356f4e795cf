// The core's messages name option fields ("box_size 8: must be in [16, 512]"); a command says them
// in its flags. `flags` maps a field, or a pair of fields one flag sets together ("hlr_min,
// hlr_max" for --hlr MIN,MAX), to the flag; fields without a flag stay as they are.
#pragma once

#include <functional>
#include <map>
#include <string>

#include "io/option_text.hpp"

namespace stampede::tools {

using FieldFlags = std::map<std::string, std::string, std::less<>>;

inline std::string with_flags(std::string message, const FieldFlags& flags) {
  for (const auto& [fields, flag] : flags) {
    if (fields.find(',') == std::string::npos) continue;
    for (std::size_t at = message.find(fields); at != std::string::npos; at = message.find(fields, at + flag.size()))
      message.replace(at, fields.size(), flag);
  }
  return io::fields_to_flags(message, [&flags](std::string_view field) {
    const auto f = flags.find(field);
    return f == flags.end() ? std::string() : f->second;
  });
}

}  // namespace stampede::tools
