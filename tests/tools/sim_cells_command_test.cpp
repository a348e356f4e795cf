// End-to-end tests of `stampede sim cells`: --help, the files of a run with --pair --tile
// --bands, and bad options refused naming the option (exit 1, nothing written).
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>
#include <vector>

#include "io/fits_file.hpp"
#include "io/meds_file.hpp"
#include "support/command_runner.hpp"
#include "support/scratch_dir.hpp"

namespace fs = std::filesystem;

namespace {

using stampede::testing::finish;
using stampede::testing::RunResult;
using stampede::testing::spawn;

class SimCellsCommand : public ::testing::Test {
 protected:
  std::string path(const std::string& name) const { return scratch.path(name); }
  RunResult run(std::vector<std::string> args) {
    args.insert(args.begin(), "cells");
    return finish(spawn(args, path("stderr.txt"), "sim", path("stdout.txt")), path("stderr.txt"));
  }
  stampede::testing::ScratchDir scratch{std::string("stampede_sim_cells_") +
                                          ::testing::UnitTest::GetInstance()->current_test_info()->name() + "_"};
};

TEST_F(SimCellsCommand, HelpListsTheOptions) {
  const RunResult r = run({"--help"});
  EXPECT_EQ(r.exit_code, 0) << r.err;
  const std::string help = [&] {
    std::ifstream in(path("stdout.txt"));
    return std::string(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
  }();
  for (const char* option : {"--layout grid|random", "--density", "--shear G1,G2", "--pair", "--psf gauss|moffat",
                             "--psf-beta", "--snr", "--noise-free", "--bands", "--model exp|bd", "--tile", "--cells",
                             "--shape-noise", "--seed"})
    EXPECT_NE(help.find(option), std::string::npos) << option;
}

TEST_F(SimCellsCommand, WritesCellsPairsBandsAndTiles) {
  const std::string out = path("run");
  const RunResult r = run({"--out", out, "--cells", "2", "--size", "80", "--buffer", "10", "--grid", "3", "--pair",
                           "--tile", "--bands", "r,i", "--psf", "moffat", "--psf-beta", "3", "--model", "bd",
                           "--threads", "2", "--seed", "5"});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  for (const char* rel : {"r/cell_0000.fits", "r/cell_0001.fits", "i/cell_0001.fits", "r/cells_meds.fits",
                          "i/cells_meds.fits", "truth.fits", "minus/truth.fits", "minus/i/cell_0001.fits",
                          "minus/r/cells_meds.fits"})
    EXPECT_TRUE(fs::exists(out + "/" + rel)) << rel;
  stampede::io::FitsFile cell = stampede::io::FitsFile::open_read(out + "/minus/i/cell_0001.fits");
  EXPECT_EQ(cell.key_double("G1"), -0.02);
  EXPECT_EQ(cell.key_string("PSFTYPE"), "moffat");
  EXPECT_EQ(cell.key_string("MODEL"), "bd");
  EXPECT_EQ(cell.key_string("BAND"), "i");
  EXPECT_EQ(cell.image_shape().nx, 80);
  stampede::io::MedsFile tile = stampede::io::MedsFile::open(out + "/i/cells_meds.fits");
  EXPECT_EQ(tile.size(), 2);
  // The run again refuses to replace its outputs, and --overwrite replaces them.
  const RunResult again = run({"--out", out, "--cells", "2", "--size", "80", "--buffer", "10", "--grid", "3"});
  EXPECT_EQ(again.exit_code, 1);
  EXPECT_NE(again.err.find("use --overwrite"), std::string::npos) << again.err;
}

TEST_F(SimCellsCommand, ReferenceIsTheReferenceShearTestsCellAndGivenOptionsOverrideIt) {
  // --reference: the reference positions, S/N 1e6, round galaxies, a 53 px PSF image; an option
  // given beside it (before or after) wins.
  const std::string out = path("ref");
  ASSERT_EQ(run({"--snr", "20", "--out", out, "--reference", "--layout", "random"}).exit_code, 0);
  stampede::io::FitsFile cell = stampede::io::FitsFile::open_read(out + "/cell_0000.fits");
  EXPECT_EQ(cell.key_double("REFPOS"), 1);
  EXPECT_EQ(cell.key_double("SNR"), 20);
  EXPECT_EQ(cell.key_double("SHAPENOI"), 0);
  EXPECT_EQ(cell.key_double("NOBJ"), 58);
  cell.move_to("PSF");
  EXPECT_EQ(cell.image_shape().nx, 53);
  ASSERT_EQ(run({"--out", path("grid"), "--reference"}).exit_code, 0);
  stampede::io::FitsFile grid = stampede::io::FitsFile::open_read(path("grid") + "/cell_0000.fits");
  EXPECT_EQ(grid.key_double("SNR"), 1e6);
  EXPECT_EQ(grid.key_double("NOBJ"), 49);
}

TEST_F(SimCellsCommand, BadOptionsAreClearErrorsNamingTheOption) {
  const std::string out = path("bad");
  const std::vector<std::pair<std::vector<std::string>, std::string>> cases = {
      {{"--layout", "hex"}, "option --layout: 'hex' is not grid or random"},
      {{"--model", "sersic"}, "option --model: 'sersic' is not exp or bd"},
      {{"--psf", "airy"}, "option --psf: 'airy' is not gauss or moffat"},
      {{"--snr", "-3"}, "--snr -3: must be > 0"},
      {{"--snr", "abc"}, "option --snr: 'abc' is not a finite number"},
      {{"--shear", "0.02"}, "option --shear: '0.02' is not two numbers G1,G2"},
      {{"--shear", "0.5,0"}, "--shear 0.5,0: |g| must be < 0.3"},
      {{"--cells", "0"}, "option --cells: 0 is outside [1, 10000000]"},
      {{"--psf-size", "32"}, "--psf-size 32: must be odd"},
      {{"--buffer", "200"}, "--buffer 200: must be >= 0 and leave an interior"},
      {{"--density", "0"}, "--density 0: must be in (0, 10000]"},
      {{"--bands", "g,g"}, "--bands: band 'g' is given twice"},
      {{"--bands", "g,G"}, "--bands: bands 'g' and 'G' differ only in case"},
      {{"--frobnicate"}, "unknown option '--frobnicate'"},
      {{"--bands", "g,r", "--bands", "i"}, "--bands is given twice: give it once (see stampede sim cells --help)"},
  };
  for (const auto& [args, message] : cases) {
    std::vector<std::string> full = {"--out", out};
    full.insert(full.end(), args.begin(), args.end());
    const RunResult r = run(full);
    EXPECT_EQ(r.exit_code, 1) << args[0];
    EXPECT_NE(r.err.find(message), std::string::npos) << args[0] << ": " << r.err;
  }
  const RunResult no_out = run({"--cells", "1"});
  EXPECT_EQ(no_out.exit_code, 1);
  EXPECT_NE(no_out.err.find("--out DIR is required"), std::string::npos) << no_out.err;
  EXPECT_FALSE(fs::exists(out + "/cell_0000.fits"));
}

}  // namespace
