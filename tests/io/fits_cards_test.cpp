// Tests for io/fits_cards: key validation and normalisation, the HIERARCH/CONTINUE card layout
// (80 columns, '&' continuation, quotes doubled and never split), and long standard and HIERARCH
// values that come back intact through CFITSIO's reader.
#include "io/fits_cards.hpp"

#include <gtest/gtest.h>

#include <string>

#include "io/fits_file.hpp"
#include "support/scratch_dir.hpp"

namespace stampede::io {
namespace {

TEST(FitsCards, StandardKeys) {
  EXPECT_TRUE(is_standard_key("NOISE_SI"));
  EXPECT_TRUE(is_standard_key("A-1"));
  EXPECT_FALSE(is_standard_key("NOISE_SIG"));  // 9 characters
  EXPECT_FALSE(is_standard_key("lower"));
  EXPECT_FALSE(is_standard_key(""));
}

TEST(FitsCards, NormaliseUpperCasesAndKeepsTheLastValueAtTheFirstPosition) {
  StringKeys out;
  std::string why;
  ASSERT_TRUE(normalise_string_keys({{"padding", "3"}, {"psf_fwhm", "2.85"}, {"PADDING", "4"}}, &out, &why));
  EXPECT_EQ(out, (StringKeys{{"PADDING", "4"}, {"PSF_FWHM", "2.85"}}));
  for (const auto& [key, value] : StringKeys{{"NAXIS2", "5"}, {"ttype1", "x"}, {"STATUS3", "x"},
                                             {"hierarch x", "y"}, {"bad=key", "x"}, {"", "x"},
                                             {"plain", "caf\xc3\xa9"}, {std::string(70, 'k'), "x"}}) {
    why.clear();
    EXPECT_FALSE(normalise_string_keys({{key, value}}, &out, &why)) << key;
    EXPECT_NE(why.find("header key '" + key + "'"), std::string::npos) << why;
  }
}

TEST(FitsCards, HierarchCardsFitEightyColumnsAndContinue) {
  const std::string key = "A_VERY_LONG_CONFIGURATION_KEY_NAME_FOR_HIERARCH";
  const std::string value = "it's quoted: " + std::string(60, 'q') + "'''" + std::string(50, 'z');
  const auto cards = hierarch_cards(key, value);
  ASSERT_GE(cards.size(), 3u);
  EXPECT_EQ(cards.front().rfind("HIERARCH " + key + " = '", 0), 0u);
  std::string joined;
  for (std::size_t i = 0; i < cards.size(); ++i) {
    const std::string& c = cards[i];
    EXPECT_LE(c.size(), 80u) << c;
    if (i > 0) {
      EXPECT_EQ(c.rfind("CONTINUE  '", 0), 0u) << c;
    }
    const bool last = i + 1 == cards.size();
    EXPECT_EQ(c.ends_with("&'"), !last) << c;
    const std::size_t open = c.find('\'');
    std::string body = c.substr(open + 1, c.size() - open - (last ? 2 : 3));
    // A doubled quote is never split across cards: every body has an even run of quotes at its end.
    std::size_t quotes = 0;
    while (quotes < body.size() && body[body.size() - 1 - quotes] == '\'') ++quotes;
    EXPECT_EQ(quotes % 2, 0u) << c;
    joined += body;
  }
  std::string unescaped;
  for (std::size_t i = 0; i < joined.size(); ++i) {
    unescaped += joined[i];
    if (joined[i] == '\'') ++i;
  }
  EXPECT_EQ(unescaped, value);
  EXPECT_EQ(hierarch_cards("LONGKEYNAME", "short"), (std::vector<std::string>{"HIERARCH LONGKEYNAME = 'short'"}));
}

TEST(FitsCards, LongValuesComeBackThroughContinueCards) {
  stampede::testing::ScratchDir scratch("stampede_fits_cards_");
  const std::string path = scratch.path("cards.fits");
  const std::string long_value(300, 'v');
  const std::string quoted = "it's a 'quoted' value, long enough for CONTINUE cards: " +
                             std::string(90, 'q') + "'" + std::string(30, 'z');
  const std::string hierarch = "A_VERY_LONG_CONFIGURATION_KEY_NAME_FOR_HIERARCH";
  int status = 0;
  fitsfile* f = nullptr;
  fits_create_diskfile(&f, path.c_str(), &status);
  fits_create_img(f, 8, 0, nullptr, &status);
  write_string_key(f, "INPUT", long_value, &status);
  write_string_key(f, hierarch, quoted, &status);
  write_string_key(f, "MINIMIZER_MAX_ITERATIONS", "30", &status);
  write_string_key(f, "EMPTY", "", &status);
  fits_close_file(f, &status);
  ASSERT_EQ(status, 0);

  FitsFile in = FitsFile::open_read(path);
  EXPECT_EQ(in.key_string("INPUT"), long_value);
  EXPECT_EQ(in.key_string(hierarch), quoted);
  EXPECT_EQ(in.key_string("minimizer_max_iterations"), "30");
  EXPECT_EQ(in.key_string("EMPTY"), "");
}

// The type CFITSIO reads a key's card as: 'C' string, 'I' integer, 'F' real ('?' if unreadable).
char card_type(fitsfile* f, const std::string& key) {
  char value[FLEN_VALUE] = {}, comment[FLEN_COMMENT] = {};
  char type = '?';
  int status = 0;
  fits_read_keyword(f, key.c_str(), value, comment, &status);
  fits_get_keytype(value, &type, &status);
  return status == 0 ? type : '?';
}

TEST(FitsCards, NumberTextOfEachType) {
  EXPECT_EQ(number_card_value("39", HeaderValueType::kInteger), "39");
  EXPECT_EQ(number_card_value("-7", HeaderValueType::kInteger), "-7");
  EXPECT_EQ(number_card_value("2.5", HeaderValueType::kInteger), "");
  EXPECT_EQ(number_card_value("3", HeaderValueType::kReal), "3.0");
  EXPECT_EQ(number_card_value("2.85", HeaderValueType::kReal), "2.85");
  EXPECT_EQ(number_card_value("1e-06", HeaderValueType::kReal), "1E-06");
  EXPECT_EQ(number_card_value("-1.5e+300", HeaderValueType::kReal), "-1.5E+300");
  for (const char* text : {"auto", "inf", "-inf", "nan", "", "5,6", "3 "})
    EXPECT_EQ(number_card_value(text, HeaderValueType::kReal), "") << text;
  EXPECT_EQ(number_card_value("39", HeaderValueType::kText), "");
}

// Numbers go in as integer and real cards (standard and HIERARCH keys) and read back as numbers
// of the same value; text, and numbers' text that is not a number, stays a string.
TEST(FitsCards, NumbersAreWrittenAsNumberCards) {
  stampede::testing::ScratchDir scratch("stampede_fits_cards_");
  const std::string path = scratch.path("numbers.fits");
  int status = 0;
  fitsfile* f = nullptr;
  fits_create_diskfile(&f, path.c_str(), &status);
  fits_create_img(f, 8, 0, nullptr, &status);
  write_header_key(f, "PADDING", "4", HeaderValueType::kInteger, &status);
  write_header_key(f, "MINIMIZER_MAX_ITERATIONS", "200", HeaderValueType::kInteger, &status);
  write_header_key(f, "PSF_BETA", "3", HeaderValueType::kReal, &status);
  write_header_key(f, "LEVMAR_LM_INIT_MU", "0.001", HeaderValueType::kReal, &status);
  write_header_key(f, "LEVMAR_EPS4", "1e-06", HeaderValueType::kReal, &status);
  write_header_key(f, "E1_MIN", "auto", HeaderValueType::kReal, &status);
  write_header_key(f, "INPUT", "123", HeaderValueType::kText, &status);
  write_header_key(f, "PADDING", "5", HeaderValueType::kInteger, &status);  // replaces the standard key
  ASSERT_EQ(status, 0);
  EXPECT_EQ(card_type(f, "PADDING"), 'I');
  EXPECT_EQ(card_type(f, "MINIMIZER_MAX_ITERATIONS"), 'I');
  EXPECT_EQ(card_type(f, "PSF_BETA"), 'F');
  EXPECT_EQ(card_type(f, "LEVMAR_LM_INIT_MU"), 'F');
  EXPECT_EQ(card_type(f, "LEVMAR_EPS4"), 'F');
  EXPECT_EQ(card_type(f, "E1_MIN"), 'C');
  EXPECT_EQ(card_type(f, "INPUT"), 'C');
  long long padding = 0, iterations = 0;
  double beta = 0, mu = 0, eps4 = 0;
  fits_read_key(f, TLONGLONG, "PADDING", &padding, nullptr, &status);
  fits_read_key(f, TLONGLONG, "MINIMIZER_MAX_ITERATIONS", &iterations, nullptr, &status);
  fits_read_key(f, TDOUBLE, "PSF_BETA", &beta, nullptr, &status);
  fits_read_key(f, TDOUBLE, "LEVMAR_LM_INIT_MU", &mu, nullptr, &status);
  fits_read_key(f, TDOUBLE, "LEVMAR_EPS4", &eps4, nullptr, &status);
  fits_close_file(f, &status);
  ASSERT_EQ(status, 0);
  EXPECT_EQ(padding, 5);
  EXPECT_EQ(iterations, 200);
  EXPECT_EQ(beta, 3.0);
  EXPECT_EQ(mu, 0.001);
  EXPECT_EQ(eps4, 1e-6);
  FitsFile in = FitsFile::open_read(path);
  EXPECT_EQ(in.key_string("E1_MIN"), "auto");
  EXPECT_EQ(in.key_string("INPUT"), "123");
}

}  // namespace
}  // namespace stampede::io
