// Command-line helpers shared by the sub-commands. A user's text echoed in an error goes through
// quoted_value() (engine/common/quoted_value.hpp): at most ~80 bytes of it, control bytes escaped.
#pragma once

#include <algorithm>
#include <array>
#include <initializer_list>
#include <charconv>
#include <cmath>
#include <set>
#include <stdexcept>
#include <string>
#include <vector>

#include "engine/common/quoted_value.hpp"

namespace stampede::tools {

using stampede::quoted_value;

// An option that takes a value, given twice: the last would silently win over the first, so it is
// refused. `seen` holds the options met so far; `flags` are the command's options without a value
// (repeating one changes nothing).
inline void refuse_repeated_option(const std::string& option, std::initializer_list<const char*> flags,
                                   std::set<std::string>* seen, const char* command) {
  if (!option.starts_with("--") || std::any_of(flags.begin(), flags.end(), [&](const char* f) { return option == f; }))
    return;
  if (!seen->insert(option).second)
    throw std::invalid_argument(option + " is given twice: give it once (see stampede " + std::string(command) + " --help)");
}

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
    throw std::invalid_argument("option " + option + ": " + quoted_value(text) + " is not a finite number");
  return v;
}

inline long long integer_value(int argc, char** argv, int* i) {
  const std::string option = argv[*i], text = option_value(argc, argv, i);
  long long v = 0;
  const char* begin = text.data() + (!text.empty() && text[0] == '+');
  const auto [ptr, ec] = std::from_chars(begin, text.data() + text.size(), v);
  if (ec != std::errc() || ptr != text.data() + text.size())
    throw std::invalid_argument("option " + option + ": " + quoted_value(text) + " is not an integer");
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

// A comma-separated list of finite numbers ("1,2.5,5"); the error names the option and the text.
inline std::vector<double> number_list(const std::string& option, const std::string& text) {
  std::vector<double> out;
  std::size_t begin = 0;
  for (;;) {
    const std::size_t end = std::min(text.find(',', begin), text.size());
    double v = 0;
    const char* first = text.data() + begin + (end > begin && text[begin] == '+');
    const auto [ptr, ec] = std::from_chars(first, text.data() + end, v);
    if (end == begin || ec != std::errc() || ptr != text.data() + end || !std::isfinite(v))
      throw std::invalid_argument("option " + option + ": " + quoted_value(text) + " is not a comma-separated list of numbers");
    out.push_back(v);
    if (end == text.size()) return out;
    begin = end + 1;
  }
}

// Exactly two numbers "A,B"; anything else is refused naming the option, the text and `form`
// (e.g. "MIN,MAX"), in these words also for a malformed list.
inline std::array<double, 2> number_pair(const std::string& option, const std::string& text, const char* form) {
  std::vector<double> v;
  try {
    v = number_list(option, text);
  } catch (const std::invalid_argument&) {
    // reported below, in this option's own terms
  }
  if (v.size() != 2) throw std::invalid_argument("option " + option + ": " + quoted_value(text) + " is not " + form);
  return {v[0], v[1]};
}

}  // namespace stampede::tools
