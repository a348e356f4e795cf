// Test helper: rewrites one 80-byte header card of a FITS file in place, to make the damaged
// headers the fuzz campaigns found (docs/reliability.md).
#pragma once

#include <gtest/gtest.h>

#include <fstream>
#include <iterator>
#include <string>

namespace stampede::testing {

// The first card of `path` starting `key` replaced by `card` (padded to 80 bytes).
inline void replace_card(const std::string& path, const std::string& key, const std::string& card) {
  std::string bytes;
  {
    std::ifstream in(path, std::ios::binary);
    bytes.assign(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
  }
  const std::size_t at = bytes.find(key);
  ASSERT_NE(at, std::string::npos) << key;
  bytes.replace(at, 80, (card + std::string(80, ' ')).substr(0, 80));
  std::ofstream(path, std::ios::binary) << bytes;
}

}  // namespace stampede::testing
