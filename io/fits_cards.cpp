// HIERARCH and CONTINUE header cards; see fits_cards.hpp.
#include "io/fits_cards.hpp"

#include <algorithm>
#include <cctype>
#include <charconv>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <string_view>

namespace stampede::io {
namespace {

std::string upper(std::string s) {
  for (char& c : s) c = static_cast<char>(std::toupper(static_cast<unsigned char>(c)));
  return s;
}

// Keys the table's structure or the catalogue writer owns; a configuration value must not
// replace them.
bool is_reserved(const std::string& key) {
  static const char* const kExact[] = {"SIMPLE", "XTENSION", "BITPIX", "NAXIS", "PCOUNT", "GCOUNT",
                                       "TFIELDS", "EXTNAME", "EXTVER", "EXTLEVEL", "THEAP", "END",
                                       "CONTINUE", "COMMENT", "HISTORY", "LONGSTRN", "HIERARCH"};
  static const char* const kIndexed[] = {"NAXIS", "TTYPE", "TFORM", "TUNIT", "TZERO", "TSCAL",
                                         "TNULL", "TCOMM", "TDIM", "TDISP", "STATUS"};
  for (const char* k : kExact) {
    if (key == k) return true;
  }
  for (std::string_view prefix : kIndexed) {
    if (key.size() > prefix.size() && key.starts_with(prefix) &&
        std::all_of(key.begin() + static_cast<std::ptrdiff_t>(prefix.size()), key.end(),
                    [](char c) { return c >= '0' && c <= '9'; })) {
      return true;
    }
  }
  return false;
}

bool printable(std::string_view s) {
  return std::ranges::all_of(s, [](char c) { return c >= 0x20 && c <= 0x7e; });
}

}  // namespace

bool is_standard_key(const std::string& key) {
  return !key.empty() && key.size() <= 8 && std::ranges::all_of(key, [](char c) {
    return (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') || c == '_' || c == '-';
  });
}

bool normalise_string_keys(const StringKeys& keys, StringKeys* out, std::string* why) {
  out->clear();
  for (const auto& [raw_key, value] : keys) {
    const std::string key = upper(raw_key);
    if (key.empty() || key.front() == ' ' || key.back() == ' ' || !printable(key) ||
        key.find('=') != std::string::npos || key.find('\'') != std::string::npos) {
      *why = "header key '" + raw_key +
             "' is not a valid FITS keyword (printable ASCII, no '=', quote or edge spaces)";
      return false;
    }
    if (is_standard_key(key) ? is_reserved(key) : key.starts_with("HIERARCH")) {
      *why = "header key '" + raw_key + "' is reserved for the table structure";
      return false;
    }
    if (!printable(value)) {
      *why = "value of header key '" + raw_key + "' has characters a FITS header cannot hold " +
             "(printable ASCII only)";
      return false;
    }
    // "HIERARCH KEY = '" plus one escaped quote and "&'" must fit one 80-character card.
    if (!is_standard_key(key) && key.size() > 80 - 17) {
      *why = "header key '" + raw_key + "' is too long for a FITS card";
      return false;
    }
    auto same = std::ranges::find_if(*out, [&](const auto& kv) { return kv.first == key; });
    if (same != out->end()) {
      same->second = value;
    } else {
      out->emplace_back(key, value);
    }
  }
  return true;
}

// Built by hand because CFITSIO 4.2's fits_update_key_longstr drops the '&' continuation marker
// when a long HIERARCH name leaves little room on the first card, so readers would lose the rest
// of the value.
std::vector<std::string> hierarch_cards(const std::string& key, const std::string& value) {
  std::vector<std::string> cards;
  std::string card = "HIERARCH " + key + " = '";
  std::size_t pos = 0;
  auto escaped = [](char c) { return c == '\'' ? std::string("''") : std::string(1, c); };
  for (;;) {
    std::string rest;
    for (std::size_t i = pos; i < value.size(); ++i) rest += escaped(value[i]);
    if (card.size() + rest.size() + 1 <= 80) {
      cards.push_back(card + rest + "'");
      return cards;
    }
    // Leave room for "&'"; normalise_string_keys's key limit guarantees one character fits.
    for (; pos < value.size(); ++pos) {
      const std::string e = escaped(value[pos]);
      if (card.size() + e.size() + 2 > 80) break;
      card += e;
    }
    cards.push_back(card + "&'");
    card = "CONTINUE  '";
  }
}

void write_string_key(fitsfile* f, const std::string& key, const std::string& value, int* status) {
  if (is_standard_key(key)) {
    fits_update_key_longstr(f, key.c_str(), value.c_str(), "", status);
  } else {
    for (const std::string& card : hierarch_cards(key, value)) {
      fits_write_record(f, card.c_str(), status);
    }
  }
}

std::string number_card_value(const std::string& value, HeaderValueType type) {
  const char* begin = value.data();
  const char* end = begin + value.size();
  if (type == HeaderValueType::kInteger) {
    std::int64_t v = 0;
    const auto [ptr, ec] = std::from_chars(begin, end, v);
    return ec == std::errc() && ptr == end ? value : std::string();
  }
  if (type != HeaderValueType::kReal) return "";
  double v = 0;
  const auto [ptr, ec] = std::from_chars(begin, end, v);
  if (ec != std::errc() || ptr != end || !std::isfinite(v)) return "";
  std::string out = value;
  const std::size_t exponent = out.find_first_of("eE");
  if (exponent != std::string::npos) {
    out[exponent] = 'E';
  } else if (out.find('.') == std::string::npos) {
    out += ".0";
  }
  return out;
}

void write_header_key(fitsfile* f, const std::string& key, const std::string& value, HeaderValueType type,
                      int* status) {
  const std::string number = number_card_value(value, type);
  if (number.empty()) return write_string_key(f, key, value, status);
  if (is_standard_key(key)) {
    char card[128];
    std::snprintf(card, sizeof card, "%-8s= %20s", key.c_str(), number.c_str());  // fixed format: value ends in column 30
    if (std::string_view(card).size() <= 80) {
      fits_update_card(f, key.c_str(), card, status);
      return;
    }
  } else {
    const std::string card = "HIERARCH " + key + " = " + number;
    if (card.size() <= 80) {
      fits_write_record(f, card.c_str(), status);
      return;
    }
  }
  write_string_key(f, key, value, status);
}

}  // namespace stampede::io
