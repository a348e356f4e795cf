// Tests for StampGridReader (io/stamp_grid): the header's stamp size and the grid it implies.
#include "io/stamp_grid.hpp"

#include <gtest/gtest.h>

#include <fstream>
#include <string>
#include <vector>

#include "io/fits_error.hpp"
#include "support/error_assertions.hpp"
#include "support/scratch_dir.hpp"

namespace stampede::io {
namespace {

using stampede::testing::Contains;
using stampede::testing::error_of;

// A 16 x 16 image with the header key STAMPSZ = stampsz.
std::string grid_file(const stampede::testing::ScratchDir& dir, long long stampsz) {
  const std::string path = dir.path("grid.fits");
  FitsFile f = FitsFile::create(path, true);
  f.write_image(16, 16, std::vector<double>(256, 1.0));
  f.write_key("STAMPSZ", stampsz, "stamp size");
  f.close();
  return path;
}

TEST(StampGridReader, ReadsTheStampSizeFromTheHeader) {
  const stampede::testing::ScratchDir dir("stampede_stamp_grid_");
  StampGridReader grid(grid_file(dir, 8));
  EXPECT_EQ(grid.stamp_size(), 8);
  EXPECT_EQ(grid.grid_nx(), 2);
  EXPECT_EQ(grid.grid_ny(), 2);
}

// Found while writing fuzz_stamp_grid: STAMPSZ = 2^32 + 8 went through an int and read as 8, so a
// corrupt header gave a 2 x 2 grid of 8-pixel stamps.
TEST(StampGridReader, RefusesAStampSizeBeyondTheIntRange) {
  const stampede::testing::ScratchDir dir("stampede_stamp_grid_");
  const std::string path = grid_file(dir, 4294967304LL);
  const std::string message = error_of<FitsError>([&] { StampGridReader grid(path); });
  EXPECT_TRUE(Contains(message, "stamp size 4294967304 does not divide the 16 x 16 image")) << message;
}

// Campaign finding F9 (fuzz_stamp_grid): a 0 x 0 image is divided by any STAMPSZ, so a corrupt
// header's 972308181 passed the reader and the fuzz target's 4-stamp batch asked std::vector for
// 3.8e18 doubles (std::length_error, uncaught). The empty image is now a FitsError.
TEST(StampGridReader, RefusesAnImageWithoutPixels) {
  const stampede::testing::ScratchDir dir("stampede_stamp_grid_");
  const std::string path = dir.path("empty.fits");
  {
    // Written card by card: the project's writer refuses an image without pixels.
    std::string header;
    for (const char* card : {"SIMPLE  =                    T", "BITPIX  =                  -32",
                             "NAXIS   =                    2", "NAXIS1  =                    0",
                             "NAXIS2  =                    0", "STAMPSZ =            972308181", "END"}) {
      std::string c(card);
      header += c + std::string(80 - c.size(), ' ');
    }
    header.resize(2880, ' ');
    std::ofstream(path, std::ios::binary) << header;
  }
  const std::string message = error_of<FitsError>([&] { StampGridReader grid(path); });
  EXPECT_TRUE(Contains(message, "the image has no pixels (0 x 0)")) << message;
}

}  // namespace
}  // namespace stampede::io
