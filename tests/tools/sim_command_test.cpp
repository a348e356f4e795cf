// End-to-end tests of `stampede sim great08`: the GalSim-mini file layout, identical sets for any
// thread count or split of the sets, readable by `stampede fit` and `stampede metrics`, bad options.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include "io/fits_file.hpp"
#include "support/command_runner.hpp"
#include "support/scratch_dir.hpp"

namespace fs = std::filesystem;

namespace {

using stampede::io::FitsFile;
using stampede::testing::finish;
using stampede::testing::RunResult;
using stampede::testing::spawn;

std::string data(const std::string& rel) { return std::string(STAMPEDE_DATA_DIR) + "/" + rel; }

class SimCommand : public ::testing::Test {
 protected:
  std::string path(const std::string& name) const { return scratch.path(name); }
  RunResult run(const std::string& command, std::vector<std::string> args, const std::string& out = "/dev/null") {
    return finish(spawn(args, path("stderr.txt"), command, out), path("stderr.txt"));
  }
  RunResult sim(const std::string& out, std::vector<std::string> extra) {
    std::vector<std::string> args = {"great08", "--out", out, "--grid", "4", "--seed", "11"};
    args.insert(args.end(), extra.begin(), extra.end());
    return run("sim", args);
  }
  stampede::testing::ScratchDir scratch{std::string("stampede_sim_") +
                                          ::testing::UnitTest::GetInstance()->current_test_info()->name() + "_"};
};

std::vector<std::string> column_names(const std::string& file) {
  FitsFile f = FitsFile::open_read(file);
  f.move_to("TRUTH");
  std::vector<std::string> names;
  for (int i = 1;; ++i) {
    const auto name = f.read_key_string("TTYPE" + std::to_string(i));
    if (!name) break;
    names.push_back(*name);
  }
  return names;
}

TEST_F(SimCommand, WritesTheGalSimMiniLayout) {
  const RunResult r = sim(path("a"), {"--sets", "1", "--noise-free"});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  FitsFile set = FitsFile::open_read(path("a/set_0.fits"));
  const auto shape = set.image_shape();
  EXPECT_EQ(shape.nx, 4 * 39);
  EXPECT_EQ(shape.ny, 4 * 39);
  EXPECT_EQ(set.key_long("BITPIX"), -32);  // float32, as GalSim's
  EXPECT_EQ(set.key_long("STAMPSZ"), 39);
  EXPECT_EQ(set.key_double("NOISESIG"), 0.0);
  EXPECT_EQ(set.key_double("PSFFWHM"), 2.85);
  EXPECT_EQ(set.key_double("PSFE2"), 0.05);
  EXPECT_FALSE(set.read_key_double("SHEAR1").has_value());  // the shear is only in the truth file
  FitsFile truth = FitsFile::open_read(path("a/truth_0.fits"));
  const double g1 = truth.key_double("SHEAR1"), g2 = truth.key_double("SHEAR2");
  EXPECT_LT(std::abs(g1), 0.05);
  EXPECT_LT(std::abs(g2), 0.05);
  truth.move_to("TRUTH");
  EXPECT_EQ(truth.table_rows(), 16);
  EXPECT_EQ(truth.read_column("g1")[5], g1);
  // The same columns, in the same order, as the GalSim sets.
  EXPECT_EQ(column_names(path("a/truth_0.fits")), column_names(data("galsim-great08-mini/nf/truth_0.fits")));
  FitsFile psf = FitsFile::open_read(path("a/psf_0.fits"));
  EXPECT_EQ(psf.image_shape().nx, 39);
  psf.move_to("PSF_NOPIX_OS");
  EXPECT_EQ(psf.image_shape().nx, 195);
  EXPECT_EQ(psf.key_long("OVERSAMP"), 5);
}

TEST_F(SimCommand, SetsAreIdenticalForAnyThreadCountAndSplit) {
  ASSERT_EQ(sim(path("two"), {"--sets", "2", "--threads", "2"}).exit_code, 0);
  ASSERT_EQ(sim(path("one"), {"--sets", "1", "--first-set", "1", "--threads", "1"}).exit_code, 0);
  FitsFile a = FitsFile::open_read(path("two/set_1.fits")), b = FitsFile::open_read(path("one/set_1.fits"));
  EXPECT_EQ(a.read_image(), b.read_image());
  FitsFile ta = FitsFile::open_read(path("two/truth_1.fits")), tb = FitsFile::open_read(path("one/truth_1.fits"));
  EXPECT_EQ(ta.key_double("SHEAR1"), tb.key_double("SHEAR1"));
  EXPECT_EQ(ta.key_long("NOISESD"), tb.key_long("NOISESD"));
  FitsFile t0 = FitsFile::open_read(path("two/truth_0.fits"));
  EXPECT_NE(t0.key_double("SHEAR1"), ta.key_double("SHEAR1"));
}

// Our simulations go through the same tools as GalSim's: fit, then metrics against the truth.
TEST_F(SimCommand, FitAndMetricsRecoverTheShear) {
  ASSERT_EQ(sim(path("s"), {"--sets", "1", "--grid", "6", "--noise-free"}).exit_code, 0);
  const RunResult f = run("fit", {path("s/set_0.fits"), "-o", path("fit.fits"), "--quiet", "--set", "psf_beta=3",
                                  "--set", "psf_fwhm=2.85", "--set", "psf_e1=0", "--set", "psf_e2=0.05"});
  ASSERT_EQ(f.exit_code, 0) << f.err;
  const RunResult m = run("metrics", {"--fit", path("fit.fits"), "--truth", path("s/truth_0.fits")}, path("report.txt"));
  ASSERT_EQ(m.exit_code, 0) << m.err;
  std::ifstream report(path("report.txt"));
  std::string line;
  int rows = 0;
  while (std::getline(report, line)) {
    std::istringstream in(line);
    int set, used;
    double g1t, g1, d1, e1, g2t, g2, e2;
    if (!(in >> set >> g1t >> g1 >> d1 >> e1 >> g2t >> g2 >> e2 >> used)) continue;
    std::printf("%s\n", line.c_str());
    // 18 noise-free ring pairs: a two-member ring cancels intrinsic shapes only to O(g e^2), so the
    // set mean scatters by its bootstrap error (~1.5e-3 here); a sign or axis error is ~0.05 off.
    EXPECT_LT(std::abs(g1 - g1t), 3 * e1) << line;
    EXPECT_LT(std::abs(g2 - g2t), 3 * e2) << line;
    EXPECT_LT(e1, 3e-3);
    EXPECT_LT(e2, 3e-3);
    EXPECT_EQ(used, 36);
    ++rows;
  }
  EXPECT_EQ(rows, 1);
}

TEST_F(SimCommand, BadOptionsAreClearErrors) {
  RunResult r = sim(path("x"), {"--size", "0.9"});
  EXPECT_NE(r.exit_code, 0);
  EXPECT_NE(r.err.find("--size 0.9"), std::string::npos) << r.err;
  r = sim(path("x"), {"--galaxy", "spiral"});
  EXPECT_NE(r.exit_code, 0);
  EXPECT_NE(r.err.find("--galaxy: 'spiral'"), std::string::npos) << r.err;
  r = sim(path("x"), {"--snr", "forty"});
  EXPECT_NE(r.exit_code, 0);
  EXPECT_NE(r.err.find("--snr: 'forty' is not a finite number"), std::string::npos) << r.err;
  r = run("sim", {"great09", "--out", path("x")});
  EXPECT_NE(r.exit_code, 0);
  EXPECT_NE(r.err.find("unknown simulation 'great09'"), std::string::npos) << r.err;
  // An existing set is not overwritten silently.
  ASSERT_EQ(sim(path("y"), {"--sets", "1", "--grid", "2", "--noise-free"}).exit_code, 0);
  r = sim(path("y"), {"--sets", "1", "--grid", "2"});
  EXPECT_NE(r.exit_code, 0);
  EXPECT_NE(r.err.find("set_0.fits' exists (use --overwrite to replace it)"), std::string::npos) << r.err;
  EXPECT_EQ(sim(path("y"), {"--sets", "1", "--grid", "2", "--overwrite"}).exit_code, 0);
}

// `sim meds`: the simulator's rules name its fields; the command line says them in its flags,
// a pair of fields one flag sets (--hlr MIN,MAX) as that flag.
TEST_F(SimCommand, SimMedsBadOptionsAreSaidInItsFlags) {
  const std::vector<std::pair<std::vector<std::string>, std::string>> cases = {
      {{"--box-size", "16"}, "psf_size 25: must be odd, >= 5 and <= --box-size"},
      {{"--hlr", "0.7,0.3"}, "--hlr 0.7,0.3: must be 0 < min <= max"},
      {{"--psf-fwhm", "1.2,0.9"}, "--psf-fwhm 1.2,0.9: must be 0 < min <= max"},
      {{"--shear", "0.3,0.1"}, "--shear 0.3,0.1: |g| must be < 0.3"},
      {{"--epochs", "4", "--images", "2"}, "--images 2: must be >= epochs"},
      {{"--bad-columns", "1.5"}, "--bad-columns 1.5: must be in [0, 1]"},
  };
  for (const auto& [args, message] : cases) {
    std::vector<std::string> full = {"meds", "--out", path("m")};
    full.insert(full.end(), args.begin(), args.end());
    const RunResult r = run("sim", full);
    EXPECT_EQ(r.exit_code, 1) << args[0];
    EXPECT_NE(r.err.find(message), std::string::npos) << args[0] << ": " << r.err;
  }
}

}  // namespace
