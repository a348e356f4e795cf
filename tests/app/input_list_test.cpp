// app/input_list: the list's syntax and the outputs it names; bad lists are errors naming the line.
#include "app/input_list.hpp"

#include <gtest/gtest.h>

#include <fstream>

#include "app/run_config.hpp"
#include "support/error_assertions.hpp"
#include "support/scratch_dir.hpp"

namespace {

using stampede::testing::Contains;
using stampede::testing::error_of;

TEST(InputList, PathsCommentsAndOutputNames) {
  const stampede::testing::ScratchDir dir("stampede_input_list_");
  const std::string list = dir.path("tiles.txt");
  std::ofstream(list) << "# tiles of the night\n  /data/a/tile_001.fits  \n\n/data/b/tile_002.fits.gz # gzip\ntile_003.fz\n";
  const auto inputs = stampede::app::read_input_list(list, "out");
  ASSERT_EQ(inputs.size(), 3u);
  EXPECT_EQ(inputs[0].input, "/data/a/tile_001.fits");
  EXPECT_EQ(inputs[0].output, "out/tile_001_fit.fits");
  EXPECT_EQ(inputs[1].input, "/data/b/tile_002.fits.gz");
  EXPECT_EQ(inputs[1].output, "out/tile_002_fit.fits");
  EXPECT_EQ(inputs[2].output, "out/tile_003_fit.fits");
}

TEST(InputList, TwoInputsWritingOneOutputEmptyAndMissingListsAreErrors) {
  const stampede::testing::ScratchDir dir("stampede_input_list_");
  const std::string list = dir.path("tiles.txt");
  std::ofstream(list) << "/a/tile.fits\n/b/tile.fits.gz\n";
  EXPECT_TRUE(Contains(error_of<stampede::io::ConfigError>([&] { stampede::app::read_input_list(list, "o"); }),
                       "tiles.txt:2: '/b/tile.fits.gz' would write 'o/tile_fit.fits', as line 1 does"));
  std::ofstream(list) << "# nothing\n\n";
  EXPECT_TRUE(Contains(error_of<stampede::io::ConfigError>([&] { stampede::app::read_input_list(list, "o"); }),
                       "names no input"));
  EXPECT_TRUE(Contains(error_of<stampede::io::ConfigError>([&] { stampede::app::read_input_list(dir.path("no.txt"), "o"); }),
                       "cannot read the input list"));
}

// Found by the Python argument fuzzer (through --config; the list reads alike): a file with no
// newline made getline grow its line until memory ran out.
TEST(InputList, AListWithoutLineEndsIsAnErrorNotAHang) {
  EXPECT_TRUE(Contains(error_of<stampede::io::ConfigError>([] { stampede::app::read_input_list("/dev/zero", "o"); }),
                       "/dev/zero:1: a line longer than 16777216 bytes: not a list of input paths"));
}

}  // namespace
