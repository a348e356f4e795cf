// Tests for tools/progress_printer: in-place redraws on a terminal, throttled whole lines elsewhere.
#include "tools/progress_printer.hpp"

#include <gtest/gtest.h>

#include <cstdio>
#include <string>

namespace {

using stampede::tools::ProgressPrinter;

// Everything written to `f` so far.
std::string contents(std::FILE* f) {
  std::fflush(f);
  std::rewind(f);
  std::string out;
  for (int c; (c = std::fgetc(f)) != EOF;) out += static_cast<char>(c);
  return out;
}

TEST(ProgressPrinter, NotOnATerminalWritesOneWholeLineEveryTenSeconds) {
  std::FILE* f = std::tmpfile();
  ASSERT_NE(f, nullptr);
  ProgressPrinter p(f, false);
  for (double t = 0.5; t < 25; t += 0.5) p.update(t, "at " + std::to_string(static_cast<int>(t)));
  p.finish();
  EXPECT_EQ(contents(f), "at 10\nat 20\n");  // no '\r', nothing before the first 10 s
  std::fclose(f);
}

TEST(ProgressPrinter, OnATerminalRedrawsInPlaceAndEndsTheLine) {
  std::FILE* f = std::tmpfile();
  ASSERT_NE(f, nullptr);
  ProgressPrinter p(f, true);
  p.update(0.5, "a");
  p.update(1.0, "b");
  p.finish();
  p.finish();  // a second finish adds nothing
  EXPECT_EQ(contents(f), "\ra\rb\n");
  std::fclose(f);
}

TEST(ProgressPrinter, NothingDrawnNothingEnded) {
  std::FILE* f = std::tmpfile();
  ASSERT_NE(f, nullptr);
  ProgressPrinter(f, true).finish();
  EXPECT_EQ(contents(f), "");
  std::fclose(f);
}

}  // namespace
