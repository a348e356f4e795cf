// Command-line helpers shared by the sub-commands.
#pragma once

#include <charconv>
#include <cmath>
#include <stdexcept>
#include <string>

namespace stampede::tools {

// The value after option argv[*i] (advancing *i); a clear error when it is missing.
inline std::string option_value(int argc, char** argv, int* i) {
  if (*i + 1 >= argc) throw std::invalid_argument(std::string("option ") + argv[*i] + " needs a value");
  return argv[++*i];
}

// The value after option argv[*i] as a finite number / an integer; the error names the option.
inline double number_value(int argc, char** argv, int* i) {
  const std::string option = argv[*i], text = option_value(argc, argv, i);
  double v = 0;
  const char* begin = text.data() + (!text.empty() && text[0] == '+');
  const auto [ptr, ec] = std::from_chars(begin, text.data() + text.size(), v);
  if (ec != std::errc() || ptr != text.data() + text.size() || !std::isfinite(v))
    throw std::invalid_argument("option " + option + ": '" + text + "' is not a finite number");
  return v;
}

inline long long integer_value(int argc, char** argv, int* i) {
  const std::string option = argv[*i], text = option_value(argc, argv, i);
  long long v = 0;
  const char* begin = text.data() + (!text.empty() && text[0] == '+');
  const auto [ptr, ec] = std::from_chars(begin, text.data() + text.size(), v);
  if (ec != std::errc() || ptr != text.data() + text.size())
    throw std::invalid_argument("option " + option + ": '" + text + "' is not an integer");
  return v;
}

// An integer option that must lie in [lo, hi]; the error names the option and the range.
inline long long integer_in(int argc, char** argv, int* i, long long lo, long long hi) {
  const std::string option = argv[*i];
  const long long v = integer_value(argc, argv, i);
  if (v < lo || v > hi)
    throw std::invalid_argument("option " + option + ": " + std::to_string(v) + " is outside [" + std::to_string(lo) +
                                ", " + std::to_string(hi) + "]");
  return v;
}

}  // namespace stampede::tools
