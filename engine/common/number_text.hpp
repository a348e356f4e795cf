// A double as people read it in messages: the shortest text that reads back as the same value
// ("0.0001", "1e+30", "nan"), never std::to_string's fixed six decimals ("0.000100", "0.000000").
#pragma once

#include <charconv>
#include <string>

namespace stampede {

inline std::string number_text(double v) {
  char buf[32];
  const auto end = std::to_chars(buf, buf + sizeof buf, v).ptr;
  return std::string(buf, end);
}

}  // namespace stampede
