// Option values as text and back: the parsers return "" on success or why not, the printers give
// the canonical form that parses back to the identical value (io/option_registry).
#pragma once

#include <charconv>
#include <cstdint>
#include <functional>
#include <string>
#include <string_view>
#include <system_error>
#include <vector>

namespace stampede::io {

std::string trim(std::string_view s);
std::string lower(std::string_view s);
// "a,b,c": the names joined by commas (a header's BANDS), "" for none.
std::string comma_list(const std::vector<std::string>& names);

// from_chars rejects a leading '+', a legitimate way to write a positive number.
std::string_view strip_plus(std::string_view s);

template <class Int>
std::string parse_integer(std::string_view text, Int* out) {
  if (text.empty()) return "empty value, expected an integer";
  const std::string_view s = strip_plus(text);
  Int v{};
  const auto [ptr, ec] = std::from_chars(s.data(), s.data() + s.size(), v);
  if (ec == std::errc::result_out_of_range) return "out of range for an integer";
  if (ec != std::errc() || ptr != s.data() + s.size()) return "expected an integer";
  *out = v;
  return "";
}

enum class DoubleKind {
  kFinite,  // a finite number
  kStart,   // finite or `auto` (NaN: from the image moments)
  kBound,   // finite, inf, -inf or `auto` (NaN: derived from the stamp)
};
std::string parse_double(std::string_view text, DoubleKind kind, double* out);
// Shortest text that parses back to exactly v (std::to_chars' guarantee), so header values read
// "0.95" rather than %.17g's "0.94999999999999996" while still round-tripping bit for bit.
std::string format_double(double v);

std::string parse_bool(std::string_view text, bool* out);
std::string format_bool(bool v);

// Integer ids separated by commas, spaces around them allowed; "" = none.
std::string parse_id_list(std::string_view text, std::vector<std::int64_t>* ids);
std::string format_id_list(const std::vector<std::int64_t>& ids);

// A message of the core, which names option fields ("e_max 0.99: must be ..."), in a front end's
// words: the field the message opens with, and any field of two words or more standing as a word
// of the text (after a space or '(', before a space, ')', ',', ':' or '=': never a part of a path),
// replaced by flag_of(field) where that is not empty.
std::string fields_to_flags(std::string_view message, const std::function<std::string(std::string_view)>& flag_of);

// Levenshtein distance between two keys, for "did you mean" suggestions.
std::size_t edit_distance(const std::string& a, const std::string& b);

}  // namespace stampede::io
