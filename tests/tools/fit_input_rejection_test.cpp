// `stampede fit` refuses, before any fitting and with a message naming the option or file, input
// it used to run on with a silent fallback or a misleading message: an invalid stamp_size, a
// noise_sigma whose weights overflow or underflow, a weight map of the wrong shape, --weight with
// noise_sigma, save_images ids not in the input, and a thread count the machine cannot hold.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include "io/fits_file.hpp"
#include "support/error_assertions.hpp"
#include "support/fit_output.hpp"

namespace {

using stampede::io::FitsFile;
using stampede::testing::Contains;
using stampede::testing::RunResult;
using stampede::testing::operator+;
using FitInputRejection = stampede::testing::FitCommandTest;

TEST_F(FitInputRejection, EachIsRefusedWithAMessageBeforeFitting) {
  stampede::testing::write_great08_stamps(path("grid.fits"), 4, 3);  // 156 x 117, STAMPSZ 39
  {
    // 150 x 117: 39 does not divide 150, which used to be the message instead of the shape.
    FitsFile w = FitsFile::create(path("weight_150.fits"), true);
    w.write_image(150, 117, std::vector<double>(150 * 117, 1.0));
  }
  std::ofstream(path("sigma.ini")) << "# noise\nnoise_sigma = 2\n";
  struct Case {
    std::vector<std::string> args;
    std::string expect;
  };
  const Case cases[] = {
      {{"--set", "stamp_size=0"}, "stamp_size = 0: must be in [3, 4096]"},
      {{"--set", "stamp_size=-39"}, "stamp_size = -39: must be in [3, 4096]"},
      {{"--set", "noise_sigma=1e-300"}, "noise_sigma = 1e-300: the pixel weight 1/noise_sigma^2 would overflow"},
      {{"--set", "noise_sigma=1e300"}, "noise_sigma = 1e+300: the pixel weight 1/noise_sigma^2 would underflow"},
      {{"--weight", path("weight_150.fits")}, "weight image is 150 x 117, the input image 156 x 117"},
      {{"--weight", path("grid.fits"), "--set", "noise_sigma=2"},
       "option 'noise_sigma' = 2 (--set) and --weight '" + path("grid.fits") + "' both give the noise"},
      {{"--weight", path("grid.fits"), "--config", path("sigma.ini")}, std::string("(") + path("sigma.ini") + ":2) and --weight"},
      {{"--set", "save_images=3,12"}, "option 'save_images': object id 12 is not in '" + path("grid.fits") + "' (ids 0..11)"},
      {{"--set", "save_images=-1"}, "object id -1 is not in"},
      // 3 x 4096 batches of 100000 39 x 39 stamps: about 30 TB.
      {{"--threads", "4096", "--set", "batch_size=100000"}, "threads = 4096: the run would need about"},
  };
  for (const Case& c : cases) {
    const RunResult r = run(std::vector<std::string>{path("grid.fits"), "-o", path("o.fits"), "--quiet"} +
                            stampede::testing::kGreat08Psf + c.args);
    EXPECT_EQ(r.exit_code, 1) << c.expect;
    EXPECT_TRUE(Contains(r.err, c.expect)) << r.err;
    for (const char* suffix : {"", ".partial", ".checkpoint"})
      EXPECT_FALSE(std::filesystem::exists(path("o.fits") + suffix)) << c.expect << ": " << suffix;
  }
  // The limits are not off by one: the extremes of the range run.
  for (const char* sigma : {"noise_sigma=1e-150", "noise_sigma=1e150"}) {
    const RunResult r = run(std::vector<std::string>{path("grid.fits"), "-o", path("o.fits"), "--overwrite", "--quiet", "--set", sigma,
                                                     "--set", "minimizer_max_iterations=2"} +
                            stampede::testing::kGreat08Psf);
    EXPECT_EQ(r.exit_code, 0) << sigma << ": " << r.err;
  }
}

}  // namespace
