// quoted_value(): a user's value as an error message shows it: in single quotes, at most ~80 bytes
// of it (the middle elided, the length given), control bytes and invalid UTF-8 escaped as \xNN, so
// a 5 MB --set value or a binary catalogue cell never floods or corrupts the terminal. Every error
// that echoes a user's value uses it. (Not `quoted`: std::quoted would win by ADL.)
#pragma once

#include <cstddef>
#include <cstdio>
#include <string>
#include <string_view>

namespace stampede {

// Values longer than this many bytes are shown as their first and last halves around "...".
inline constexpr std::size_t kQuotedMaxBytes = 80;
// Enough for any path the system accepts (PATH_MAX): a file name is never elided.
inline constexpr std::size_t kQuotedPathMaxBytes = 4096;

namespace quoted_detail {

// Length of the well-formed UTF-8 sequence starting at s[i] (1 for printable ASCII), or 0 when the
// byte must be escaped (a control byte, DEL, or a byte not starting a well-formed sequence).
inline std::size_t printable_run(std::string_view s, std::size_t i) {
  const auto c = static_cast<unsigned char>(s[i]);
  if (c >= 0x20 && c < 0x7f) return 1;
  const std::size_t n = c >= 0xc2 && c <= 0xdf ? 2 : c >= 0xe0 && c <= 0xef ? 3 : c >= 0xf0 && c <= 0xf4 ? 4 : 0;
  if (n == 0 || i + n > s.size()) return 0;
  for (std::size_t k = 1; k < n; ++k)
    if ((static_cast<unsigned char>(s[i + k]) & 0xc0) != 0x80) return 0;
  const auto c1 = static_cast<unsigned char>(s[i + 1]);  // no overlong forms, surrogates or > U+10FFFF
  if ((c == 0xe0 && c1 < 0xa0) || (c == 0xed && c1 > 0x9f) || (c == 0xf0 && c1 < 0x90) || (c == 0xf4 && c1 > 0x8f))
    return 0;
  return n;
}

// Appends s[begin, end) escaped; a UTF-8 sequence cut by `end` is escaped byte by byte.
inline void append_escaped(std::string& out, std::string_view s, std::size_t begin, std::size_t end) {
  for (std::size_t i = begin; i < end;) {
    const std::size_t n = printable_run(s.substr(0, end), i);
    if (n == 0) {
      char hex[5];
      std::snprintf(hex, sizeof hex, "\\x%02x", static_cast<unsigned char>(s[i]));
      out += hex;
      ++i;
    } else {
      if (n == 1 && s[i] == '\\') out += '\\';  // so that "\x41" written by the user reads back unambiguously
      out.append(s.substr(i, n));
      i += n;
    }
  }
}

}  // namespace quoted_detail

// 'value', or 'first 40 bytes...last 40 bytes' (N bytes) for a longer one (limit: max_bytes).
inline std::string quoted_value(std::string_view value, std::size_t max_bytes = kQuotedMaxBytes) {
  std::string out = "'";
  if (value.size() <= max_bytes) {
    quoted_detail::append_escaped(out, value, 0, value.size());
    return out + "'";
  }
  const std::size_t half = max_bytes / 2;
  quoted_detail::append_escaped(out, value, 0, half);
  out += "...";
  quoted_detail::append_escaped(out, value.substr(value.size() - half), 0, half);
  return out + "' (" + std::to_string(value.size()) + " bytes)";
}

}  // namespace stampede
