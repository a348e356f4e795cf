// `stampede metrics` refuses what would give a wrong answer as a good one: a fit table paired with
// the truth file of another set (matched by the input identity the fit recorded, INSETID), and a
// set whose rows are all excluded (it used to give NaN m and c beside a finite Q).
#include <gtest/gtest.h>

#include <string>
#include <vector>

#include "io/fits_file.hpp"
#include "support/error_assertions.hpp"
#include "support/fit_output.hpp"

namespace {

using stampede::io::FitsFile;
using stampede::testing::Contains;
using stampede::testing::finish;
using stampede::testing::RunResult;
using stampede::testing::spawn;
using stampede::testing::operator+;

std::string data(const std::string& name) { return std::string(STAMPEDE_DATA_DIR) + "/galsim-great08-mini/nf/" + name; }

class MetricsCommand : public stampede::testing::FitCommandTest {
 protected:
  RunResult metrics(const std::vector<std::string>& args) {
    return finish(spawn(args, path("metrics_err.txt"), "metrics", path("report.txt")), path("metrics_err.txt"));
  }
};

TEST_F(MetricsCommand, AFitPairedWithAnotherSetsTruthIsRefused) {
  // Cheap fits: only the recorded identity matters here.
  const std::vector<std::string> cheap = {"--quiet", "--set", "renderer=upsampled", "--set", "upsampling=1", "--set", "n_central_pixels_to_upsample=0",
                                          "--set", "padding=0"};
  for (const char* k : {"0", "1"}) {
    const RunResult r = run(std::vector<std::string>{data(std::string("set_") + k + ".fits"), "-o",
                                                     path(std::string("fit_") + k + ".fits")} +
                            stampede::testing::kGreat08Psf + cheap);
    ASSERT_EQ(r.exit_code, 0) << r.err;
  }
  FitsFile fit0 = FitsFile::open_read(path("fit_0.fits"));
  fit0.move_to("RESULTS");
  EXPECT_EQ(fit0.read_key_string("INSETID"), "SEED=7 SETIDX=0 NOISESD=0");

  const RunResult right = metrics({"--fit", path("fit_0.fits"), "--truth", data("truth_0.fits"), "--fit",
                                   path("fit_1.fits"), "--truth", data("truth_1.fits")});
  EXPECT_EQ(right.exit_code, 0) << right.err;
  // Same grid, same ids, same number of rows: only the recorded identity tells the sets apart.
  const RunResult swapped = metrics({"--fit", path("fit_0.fits"), "--truth", data("truth_1.fits"), "--fit",
                                     path("fit_1.fits"), "--truth", data("truth_0.fits")});
  EXPECT_EQ(swapped.exit_code, 1);
  EXPECT_TRUE(Contains(swapped.err, "fit_0.fits[HDU 1 'RESULTS'] is a fit of set 'SEED=7 SETIDX=0 NOISESD=0' (INSETID), but " +
                                        data("truth_1.fits") + " is the truth of set 'SEED=7 SETIDX=1 NOISESD=0'"))
      << swapped.err;
}

// A set with no usable row has no shear estimate: refused, naming the table.
TEST_F(MetricsCommand, ASetWhoseRowsAreAllExcludedIsRefused) {
  auto write_fit = [&](const std::string& file, double status) {
    std::vector<double> id, e, st(400, status), zero(400, 0.0), psf(400, 0.05);
    for (int i = 0; i < 400; ++i) {
      id.push_back(i);
      e.push_back(0.01 * (i % 7));
    }
    FitsFile f = FitsFile::create(file, true);
    f.write_empty_image();
    f.write_table("RESULTS", {{"id", true, id}, {"e1", false, e}, {"e2", false, e}, {"status", true, st},
                              {"flags", true, zero}, {"psf_e1", false, zero}, {"psf_e2", false, psf}});
  };
  write_fit(path("good.fits"), 0);
  write_fit(path("excluded.fits"), 3);  // no_data
  const RunResult r = metrics({"--fit", path("good.fits"), "--truth", data("truth_0.fits"), "--fit",
                               path("excluded.fits"), "--truth", data("truth_1.fits")});
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_TRUE(Contains(r.err, "excluded.fits[HDU 1 'RESULTS']: all 400 rows are excluded")) << r.err;
  write_fit(path("excluded.fits"), 0);
  EXPECT_EQ(metrics({"--fit", path("good.fits"), "--truth", data("truth_0.fits"), "--fit", path("excluded.fits"),
                     "--truth", data("truth_1.fits")})
                .exit_code,
            0);
}

}  // namespace
