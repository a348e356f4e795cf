// number_text: messages show a value as typed (shortest round trip), never fixed six decimals
// (issue 31: "metacal_step = 0.000000" for a step of 1e-7).
#include <gtest/gtest.h>

#include <cmath>
#include <string>

#include "engine/common/number_text.hpp"
#include "engine/metacal/metacal_fitter.hpp"

namespace {

using stampede::number_text;

TEST(NumberText, ShortestTextThatReadsBackTheSameValue) {
  EXPECT_EQ(number_text(1e-7), "1e-07");
  EXPECT_EQ(number_text(0.01), "0.01");
  EXPECT_EQ(number_text(1e30), "1e+30");
  EXPECT_EQ(number_text(-100), "-100");
  EXPECT_EQ(number_text(NAN), "nan");
  EXPECT_EQ(std::stod(number_text(0.1 + 0.2)), 0.1 + 0.2);
}

TEST(NumberText, MetacalOptionErrorsShowTheValueGiven) {
  stampede::MetacalOptions o;
  o.step = 1e-7;
  o.step = -1e-7;
  std::string why;
  EXPECT_FALSE(o.IsValid(&why));
  EXPECT_EQ(why, "metacal_step = -1e-07: must be in [0.001, 0.1]");
}

}  // namespace
