// `stampede fit --catalog`: what the catalogue's rows mean. Catalogue input follows the grid's
// weighting rules (noise_sigma = 0 unweighted, else 1/noise_sigma^2) and `calibrate apply` treats
// its rows alike; ids are 64-bit integers end to end, a non-integer id is an error naming the row;
// a position however far or not finite is a flagged row; a bad catalogue is refused up front.
#include <fitsio.h>
#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include "io/fits_file.hpp"
#include "support/error_assertions.hpp"
#include "support/fit_output.hpp"

namespace {

using stampede::io::FitsFile;
using stampede::testing::column;
using stampede::testing::Contains;
using stampede::testing::finish;
using stampede::testing::kGreat08Psf;
using stampede::testing::RunResult;
using stampede::testing::spawn;
using stampede::testing::operator+;

constexpr int kStamp = 39, kNx = 4, kNy = 3;
constexpr std::uint32_t kUnweighted = 1u << 6, kEdge = 1u << 16;

// 1-based centre of grid stamp (ix, iy): a catalogue object there is cut from the grid stamp's pixels.
double centre(int i) { return i * kStamp + 20.0; }

// A FITS catalogue whose id column is 64-bit ('K', ids written exactly) or double ('D').
void write_fits_catalogue(const std::string& path, const std::vector<long long>& ids, const std::vector<double>& double_ids,
                          const std::vector<double>& x, const std::vector<double>& y) {
  std::filesystem::remove(path);
  fitsfile* f = nullptr;
  int status = 0;
  const bool integer = double_ids.empty();
  char id[] = "id", xs[] = "x", ys[] = "y", k[] = "K", d[] = "D";
  char* ttype[] = {id, xs, ys};
  char* tform[] = {integer ? k : d, d, d};
  fits_create_file(&f, path.c_str(), &status);
  fits_create_tbl(f, BINARY_TBL, 0, 3, ttype, tform, nullptr, "OBJECTS", &status);
  std::vector<long long> i64 = ids;
  std::vector<double> dd = double_ids, xx = x, yy = y;
  if (integer) fits_write_col(f, TLONGLONG, 1, 1, 1, static_cast<LONGLONG>(i64.size()), i64.data(), &status);
  else fits_write_col(f, TDOUBLE, 1, 1, 1, static_cast<LONGLONG>(dd.size()), dd.data(), &status);
  fits_write_col(f, TDOUBLE, 2, 1, 1, static_cast<LONGLONG>(xx.size()), xx.data(), &status);
  fits_write_col(f, TDOUBLE, 3, 1, 1, static_cast<LONGLONG>(yy.size()), yy.data(), &status);
  fits_close_file(f, &status);
  ASSERT_EQ(status, 0) << path;
}

std::vector<long long> integer_column(const std::string& file, const std::string& name) {
  FitsFile f = FitsFile::open_read(file);
  f.move_to("RESULTS");
  std::vector<long long> v(static_cast<std::size_t>(f.table_rows()));
  f.read_column_rows(name, 0, v);
  return v;
}

class FitCatalogueInput : public stampede::testing::FitCommandTest {
 protected:
  void SetUp() override { stampede::testing::write_great08_stamps(path("image.fits"), kNx, kNy); }
  RunResult fit(const std::string& catalogue, const std::string& out, std::vector<std::string> extra = {}) {
    // --overwrite: a test may fit several catalogues into one output.
    return run(std::vector<std::string>{path("image.fits"), "-o", out, "--overwrite", "--catalog", catalogue, "--quiet",
                                        "--threads", "2"} +
               kGreat08Psf + extra);
  }
  void write_text(const std::string& name, const std::string& text) { std::ofstream(path(name)) << text; }
  // The interior objects (1000 + grid index) at the grid's stamps.
  std::string interior_catalogue() {
    std::ostringstream s;
    s.precision(17);
    for (int iy = 0; iy < kNy; ++iy)
      for (int ix = 0; ix < kNx; ++ix) s << 1000 + iy * kNx + ix << " " << centre(ix) << " " << centre(iy) << "\n";
    return s.str();
  }
};

// Every fitted column (snr and flags included) of the catalogue run equals the grid run's, for an
// unweighted and a weighted run; before, the catalogue fitted with weight 1 whatever noise_sigma.
TEST_F(FitCatalogueInput, WeightingFollowsTheGridsRules) {
  write_text("cat.txt", interior_catalogue());
  const std::vector<std::string> fitted = {"x0", "y0", "e1", "e2", "radius", "bulge_A", "disc_A", "flux", "e1_err",
                                           "e2_err", "snr", "chi2", "likelihood", "n_iter", "status", "flags"};
  for (const char* sigma : {"0", "2.5"}) {
    const std::vector<std::string> noise = {"--set", std::string("noise_sigma=") + sigma};
    const RunResult g = run(std::vector<std::string>{path("image.fits"), "-o", path("grid.fits"), "--overwrite", "--quiet"} + kGreat08Psf + noise);
    ASSERT_EQ(g.exit_code, 0) << g.err;
    const RunResult c = fit(path("cat.txt"), path("cat.fits"), noise);
    ASSERT_EQ(c.exit_code, 0) << c.err;
    for (const std::string& name : fitted) {
      const auto a = column(path("cat.fits"), name), b = column(path("grid.fits"), name);
      ASSERT_EQ(a.size(), b.size());
      for (std::size_t i = 0; i < a.size(); ++i)
        EXPECT_TRUE(a[i] == b[i] || (std::isnan(a[i]) && std::isnan(b[i]))) << name << " row " << i << " sigma " << sigma
                                                                            << ": " << a[i] << " vs " << b[i];
    }
    const auto flags = column(path("cat.fits"), "flags"), snr = column(path("cat.fits"), "snr");
    for (std::size_t i = 0; i < flags.size(); ++i) {
      EXPECT_EQ((static_cast<std::uint32_t>(flags[i]) & kUnweighted) != 0, std::string(sigma) == "0") << i;
      EXPECT_EQ(std::isnan(snr[i]), std::string(sigma) == "0") << i;
    }
  }
}

// `calibrate apply` gives the catalogue's unweighted rows what it gives the grid's: no calibrated e.
TEST_F(FitCatalogueInput, CalibrateApplyTreatsUnweightedCatalogueRowsAsTheGrids) {
  write_text("cat.txt", interior_catalogue());
  ASSERT_EQ(fit(path("cat.txt"), path("cat.fits"), {"--set", "noise_sigma=0"}).exit_code, 0);
  // The small build of calibrate_command_test (48 points x 3 noise pairs).
  const RunResult b = finish(spawn({"build", "-o", path("cal.fits"), "--radii", "1.2,2", "--bulge-fractions", "0,1",
                                    "--e-steps", "6", "--e-max", "0.5", "--realisations", "3", "--set", "stamp_size=25",
                                    "--set", "noise_sigma=1", "--set", "psf_e2=0.05", "--threads", "2", "--quiet"},
                                   path("build.txt"), "calibrate"),
                             path("build.txt"));
  ASSERT_EQ(b.exit_code, 0) << b.err;
  const RunResult a = finish(spawn({"apply", path("cat.fits"), "--calibration", path("cal.fits"), "--deep", path("cat.fits"),
                                    "-o", path("cal_cat.fits"), "--quiet"},
                                   path("apply.txt"), "calibrate"),
                             path("apply.txt"));
  ASSERT_EQ(a.exit_code, 0) << a.err;
  const auto e1 = column(path("cal_cat.fits"), "e1_cal"), e2 = column(path("cal_cat.fits"), "e2_cal");
  ASSERT_EQ(e1.size(), static_cast<std::size_t>(kNx * kNy));
  for (std::size_t i = 0; i < e1.size(); ++i) EXPECT_TRUE(std::isnan(e1[i]) && std::isnan(e2[i])) << i;
}

// 64-bit ids come out as they went in, through text and FITS catalogues and the FITS and text tables.
TEST_F(FitCatalogueInput, SixtyFourBitIdsSurviveTheRoundTrip) {
  const std::vector<long long> ids = {12345678901234567LL, (1LL << 62) + 1, -9223372036854775807LL - 1, 7};
  const std::vector<double> x = {centre(0), centre(1), centre(2), centre(3)}, y = {centre(0), centre(1), centre(2), centre(0)};
  std::ostringstream text;
  text.precision(17);
  for (std::size_t i = 0; i < ids.size(); ++i) text << ids[i] << " " << x[i] << " " << y[i] << "\n";
  write_text("cat.txt", text.str());
  write_fits_catalogue(path("cat_k.fits"), ids, {}, x, y);
  for (const std::string& cat : {path("cat.txt"), path("cat_k.fits")}) {
    const RunResult r = fit(cat, path("out.fits"), {"--set", "noise_sigma=1", "--text", path("out.txt")});
    ASSERT_EQ(r.exit_code, 0) << r.err;
    EXPECT_EQ(integer_column(path("out.fits"), "id"), ids) << cat;
    std::ifstream in(path("out.txt"));
    std::string line;
    std::vector<long long> from_text;
    while (std::getline(in, line))
      if (!line.empty() && line[0] != '#') from_text.push_back(std::stoll(line.substr(0, line.find(' '))));
    EXPECT_EQ(from_text, ids) << cat;
  }
}

TEST_F(FitCatalogueInput, NonIntegerIdIsAnErrorNamingTheRow) {
  for (const char* bad : {"1.7", "1e30", "nan", "abc", "99999999999999999999", "9007199254740993.0"}) {
    write_text("cat.txt", std::string("1 20 20\n# a comment\n") + bad + " 59 20\n");
    const RunResult r = fit(path("cat.txt"), path("out.fits"));
    EXPECT_EQ(r.exit_code, 1) << bad;
    EXPECT_TRUE(Contains(r.err, path("cat.txt") + ":3: id '" + bad + "' is not a 64-bit integer")) << r.err;
  }
  for (double bad : {1.7, 1e30, std::nan("")}) {
    write_fits_catalogue(path("cat_d.fits"), {}, {1.0, 2.0, bad}, {20, 59, 98}, {20, 20, 20});
    const RunResult r = fit(path("cat_d.fits"), path("out.fits"));
    EXPECT_EQ(r.exit_code, 1) << bad;
    EXPECT_TRUE(Contains(r.err, "row 3: id ")) << r.err;
    EXPECT_TRUE(Contains(r.err, "in column 'id' is not a 64-bit integer")) << r.err;
  }
  // Integral doubles are ids: a float id column as many tools write them.
  write_fits_catalogue(path("cat_d.fits"), {}, {1.0, 3.0e15, -4.0}, {20, 59, 98}, {20, 20, 20});
  ASSERT_EQ(fit(path("cat_d.fits"), path("out.fits")).exit_code, 0);
  EXPECT_EQ(integer_column(path("out.fits"), "id"), (std::vector<long long>{1, 3000000000000000LL, -4}));
}

// Before, |x| >= 9.2e18 overflowed a long in the cutout arithmetic (undefined behaviour) and the
// row lacked the edge flag; now every such position is an edge-flagged row with no data.
TEST_F(FitCatalogueInput, FarOrNonFinitePositionsAreFlaggedRows) {
  const std::vector<std::string> xs = {"9.3e18", "-9.3e18", "1e300", "-1e300", "1e400", "inf", "-inf", "nan", "20", "20"};
  const std::vector<std::string> ys = {"20", "20", "20", "20", "20", "20", "20", "20", "1e300", "nan"};
  std::string text;
  for (std::size_t i = 0; i < xs.size(); ++i) text += std::to_string(i + 1) + " " + xs[i] + " " + ys[i] + "\n";
  text += "99 59 20\n";  // and a real object
  write_text("cat.txt", text);
  const RunResult r = fit(path("cat.txt"), path("out.fits"), {"--set", "noise_sigma=1"});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const auto flags = column(path("out.fits"), "flags"), status = column(path("out.fits"), "status");
  ASSERT_EQ(flags.size(), xs.size() + 1);
  for (std::size_t i = 0; i < xs.size(); ++i) {
    EXPECT_TRUE(static_cast<std::uint32_t>(flags[i]) & kEdge) << xs[i] << ", " << ys[i];
    EXPECT_EQ(status[i], 3) << xs[i] << ", " << ys[i];  // FitStatus::kNoData
  }
  EXPECT_EQ(static_cast<std::uint32_t>(flags.back()) & kEdge, 0u);
  EXPECT_EQ(status.back(), 0);
}

TEST_F(FitCatalogueInput, BadCataloguesAreRefusedBeforeFitting) {
  auto refused = [&](const std::string& catalogue, const std::string& message, std::vector<std::string> extra = {}) {
    const RunResult r = fit(catalogue, path("out.fits"), extra);
    EXPECT_EQ(r.exit_code, 1) << message;
    EXPECT_TRUE(Contains(r.err, message)) << r.err;
    EXPECT_FALSE(std::filesystem::exists(path("out.fits.partial"))) << message;
  };
  std::filesystem::create_directory(path("dir"));
  refused(path("dir"), "catalogue '" + path("dir") + "' is a directory");
  write_text("dup.txt", "1 20 20\n2 59 20\n\n1 98 20\n");
  refused(path("dup.txt"), path("dup.txt") + ": id 1 on lines 1 and 4: object ids must be unique");
  write_fits_catalogue(path("dup.fits"), {5, 6, 6}, {}, {20, 59, 98}, {20, 20, 20});
  refused(path("dup.fits"), ": id 6 in rows 2 and 3: object ids must be unique");
  write_text("cat.txt", "1 20 20\n2 59 20\n");
  refused(path("cat.txt"), "option 'save_images': object id 3 is not in catalogue '" + path("cat.txt") + "'",
          {"--set", "save_images=2,3"});
}

}  // namespace
