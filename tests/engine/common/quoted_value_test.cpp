// quoted_value: short printable values as they are, long ones elided to ~80 bytes with their
// length, control bytes and invalid UTF-8 escaped, valid UTF-8 kept.
#include <gtest/gtest.h>

#include <string>

#include "engine/common/quoted_value.hpp"

namespace {

using stampede::quoted_value;

TEST(QuotedValue, ShortPrintableValuesAreQuotedAsTheyAre) {
  EXPECT_EQ(quoted_value("abc"), "'abc'");
  EXPECT_EQ(quoted_value(""), "''");
  EXPECT_EQ(quoted_value("données"), "'données'");  // valid UTF-8 is printable
  EXPECT_EQ(quoted_value(std::string(80, 'x')), "'" + std::string(80, 'x') + "'");
}

TEST(QuotedValue, ControlAndInvalidBytesAreEscaped) {
  EXPECT_EQ(quoted_value(std::string("a\0b\n\x1b[2J\x7f", 9)), "'a\\x00b\\x0a\\x1b[2J\\x7f'");
  EXPECT_EQ(quoted_value("\xff\xfe"), "'\\xff\\xfe'");
  EXPECT_EQ(quoted_value("\xc3"), "'\\xc3'");          // a cut sequence
  EXPECT_EQ(quoted_value("\xc0\xaf"), "'\\xc0\\xaf'");  // an overlong '/'
  EXPECT_EQ(quoted_value("\xed\xa0\x80"), "'\\xed\\xa0\\x80'");  // a surrogate
  EXPECT_EQ(quoted_value("a\\x41"), "'a\\\\x41'");     // a backslash the user wrote is doubled
}

TEST(QuotedValue, LongValuesKeepTheirEndsAndSayTheirLength) {
  const std::string big = "BEGIN" + std::string(5'000'000, 'x') + "END";
  const std::string q = quoted_value(big);
  EXPECT_EQ(q, "'BEGIN" + std::string(35, 'x') + "..." + std::string(37, 'x') + "END' (5000008 bytes)");
  EXPECT_LE(q.size(), 110u);
  // Escapes are not counted in the limit, but the bytes shown are.
  EXPECT_EQ(quoted_value(std::string(100, '\x01')).size(), 2 + 80 * 4 + 3 + std::string(" (100 bytes)").size());
  // A path limit keeps any real path whole.
  const std::string path = "/data/" + std::string(200, 'd') + "/set_0.fits";
  EXPECT_EQ(quoted_value(path, stampede::kQuotedPathMaxBytes), "'" + path + "'");
}

}  // namespace
