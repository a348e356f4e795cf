// String-valued FITS header keys of any length: keys that are not standard 8-character FITS
// keywords (configuration keys such as `minimizer_max_iterations`) as HIERARCH cards, values longer
// than one card continued on CONTINUE cards (the LONGSTRN convention).
//
// Includes fitsio.h: include this only from .cpp files that already use CFITSIO.
#pragma once

#include <fitsio.h>

#include <string>
#include <utility>
#include <vector>

#include "io/header_value.hpp"

namespace stampede::io {

using StringKeys = std::vector<std::pair<std::string, std::string>>;

// True for a standard keyword: 1 to 8 characters of [A-Z0-9_-].
bool is_standard_key(const std::string& key);

// Checks `keys` and writes to *out their upper-cased form (FITS lookups ignore case), keeping
// the last value of a repeated key at the position of its first appearance. Refuses (false, *why
// naming the key) keys that are not printable ASCII or hold '=' or a quote, keys reserved for a
// table's structure (NAXIS2, TTYPE3, EXTNAME, STATUS0, ...), values that are not printable
// ASCII, and HIERARCH keys too long for one card.
bool normalise_string_keys(const StringKeys& keys, StringKeys* out, std::string* why);

// The cards of a HIERARCH string key: "HIERARCH KEY = 'VALUE'", continued on "CONTINUE  '...'"
// cards with a trailing '&' where the value does not fit. Quotes are doubled and never split.
// `key` must have passed normalise_string_keys.
std::vector<std::string> hierarch_cards(const std::string& key, const std::string& value);

// Writes KEY = 'VALUE' to the current HDU of `f`: a standard key through
// fits_update_key_longstr (CONTINUE cards for a long value, replacing an existing key), another
// as hierarch_cards appended. CFITSIO convention: does nothing if *status is non-zero on entry.
void write_string_key(fitsfile* f, const std::string& key, const std::string& value, int* status);

// The FITS text of `value` as a number card of `type`: an integer as it is; a finite real with an
// upper-case exponent and, where it has neither, a decimal point added ("3" -> "3.0", "1e-06" ->
// "1E-06"), so readers see its type. Empty for kText and for text that is not such a number
// ('auto', 'inf', '5,6').
std::string number_card_value(const std::string& value, HeaderValueType type);

// Writes `value` as a number card of `type` (number_card_value) where it is one and the card fits
// 80 columns, else as write_string_key does. Same key rules and status convention.
void write_header_key(fitsfile* f, const std::string& key, const std::string& value, HeaderValueType type,
                      int* status);

}  // namespace stampede::io
