// Option values as text and back; see option_text.hpp.
#include "io/option_text.hpp"

#include <algorithm>
#include <cctype>
#include <cmath>

#include "engine/common/quoted_value.hpp"

namespace stampede::io {

std::string trim(std::string_view s) {
  const auto first = s.find_first_not_of(" \t\r\n\f\v");
  if (first == std::string_view::npos) return "";
  const auto last = s.find_last_not_of(" \t\r\n\f\v");
  return std::string(s.substr(first, last - first + 1));
}

std::string comma_list(const std::vector<std::string>& names) {
  std::string out;
  for (const std::string& n : names) out += (out.empty() ? "" : ",") + n;
  return out;
}

std::string lower(std::string_view s) {
  std::string out(s);
  for (char& c : out) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return out;
}

std::string_view strip_plus(std::string_view s) {
  if (s.size() > 1 && s[0] == '+' && s[1] != '+' && s[1] != '-') s.remove_prefix(1);
  return s;
}

std::string parse_double(std::string_view text, DoubleKind kind, double* out) {
  if (text.empty()) return "empty value, expected a number";
  if (kind != DoubleKind::kFinite && lower(text) == "auto") {
    *out = NAN;
    return "";
  }
  const std::string_view s = strip_plus(text);
  double v = 0;
  const auto [ptr, ec] = std::from_chars(s.data(), s.data() + s.size(), v);
  if (ec == std::errc::result_out_of_range) return "out of range for a double";
  if (ec != std::errc() || ptr != s.data() + s.size()) return "expected a number";
  // "nan" parses, but NaN is spelled `auto` where it means something, and is an error elsewhere.
  if (std::isnan(v)) return kind == DoubleKind::kFinite ? "expected a finite number" : "expected a number or 'auto'";
  if (std::isinf(v) && kind != DoubleKind::kBound) return "must be finite";
  *out = v;
  return "";
}

std::string format_double(double v) {
  if (std::isnan(v)) return "auto";
  if (std::isinf(v)) return v > 0 ? "inf" : "-inf";
  char buf[64];
  const auto [ptr, ec] = std::to_chars(buf, buf + sizeof(buf), v);
  return ec == std::errc() ? std::string(buf, ptr) : std::string("?");
}

std::string parse_bool(std::string_view text, bool* out) {
  const std::string s = lower(text);
  if (s == "true" || s == "yes" || s == "1") {
    *out = true;
  } else if (s == "false" || s == "no" || s == "0") {
    *out = false;
  } else {
    return "expected true/false, yes/no or 1/0";
  }
  return "";
}

std::string format_bool(bool v) { return v ? "true" : "false"; }

std::string parse_id_list(std::string_view text, std::vector<std::int64_t>* ids) {
  ids->clear();
  if (trim(text).empty()) return "";
  std::size_t pos = 0;
  while (true) {
    const std::size_t comma = text.find(',', pos);
    const std::string item = trim(text.substr(pos, comma == std::string_view::npos ? text.npos : comma - pos));
    std::int64_t id = 0;
    if (item.empty() || !parse_integer(item, &id).empty())
      return "expected comma-separated integer object ids, got " + quoted_value(item);
    ids->push_back(id);
    if (comma == std::string_view::npos) return "";
    pos = comma + 1;
  }
}

std::string format_id_list(const std::vector<std::int64_t>& ids) {
  std::string out;
  for (std::size_t i = 0; i < ids.size(); ++i) {
    if (i) out += ',';
    out += std::to_string(ids[i]);  // appended apart: GCC 12 warns falsely (-Wrestrict) on "," + string
  }
  return out;
}

std::size_t edit_distance(const std::string& a, const std::string& b) {
  std::vector<std::size_t> row(b.size() + 1);
  for (std::size_t j = 0; j <= b.size(); ++j) row[j] = j;
  for (std::size_t i = 1; i <= a.size(); ++i) {
    std::size_t diag = row[0];
    row[0] = i;
    for (std::size_t j = 1; j <= b.size(); ++j) {
      const std::size_t up = row[j];
      row[j] = std::min({row[j] + 1, row[j - 1] + 1, diag + (a[i - 1] == b[j - 1] ? 0 : 1)});
      diag = up;
    }
  }
  return row[b.size()];
}

std::string fields_to_flags(std::string_view message, const std::function<std::string(std::string_view)>& flag_of) {
  auto word = [](char c) { return std::isalnum(static_cast<unsigned char>(c)) || c == '_'; };
  auto opens = [](char c) { return c == ' ' || c == '('; };
  auto closes = [](char c) { return c == ' ' || c == ')' || c == ',' || c == ':' || c == '='; };
  std::string out;
  for (std::size_t i = 0; i < message.size();) {
    if (!word(message[i]) || (i > 0 && !opens(message[i - 1]))) {
      out += message[i++];
      continue;
    }
    std::size_t j = i;
    while (j < message.size() && word(message[j])) ++j;
    const std::string_view token = message.substr(i, j - i);
    const bool whole = j == message.size() || closes(message[j]);
    const std::string flag = whole && (i == 0 || token.find('_') != std::string_view::npos) ? flag_of(token) : "";
    out += flag.empty() ? std::string(token) : flag;
    i = j;
  }
  return out;
}

}  // namespace stampede::io
