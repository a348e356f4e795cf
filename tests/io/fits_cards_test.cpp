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

}  // namespace
}  // namespace stampede::io
