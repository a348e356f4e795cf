// `stampede metrics` refuses what would give a wrong answer as a good one: a fit table paired with
// the truth file of another set (matched by the input identity the fit recorded, INSETID), and a
// set whose rows are all excluded (it used to give NaN m and c beside a finite Q).
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <tuple>
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

std::string text_of(const std::string& file) {
  std::ifstream in(file);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

class MetricsCommand : public stampede::testing::FitCommandTest {
 protected:
  RunResult metrics(const std::vector<std::string>& args) {
    return finish(spawn(args, path("metrics_err.txt"), "metrics", path("report.txt")), path("metrics_err.txt"));
  }
  // A metacal table of 400 rows whose radii (0.6 .. 1.56 px) straddle 1.0 x Gamma / 3.2, the
  // sheared images' radii a little apart from the noshear one's.
  void write_metacal_table() {
    constexpr double kGamma = 3.2;
    std::vector<std::vector<double>> c(24);
    const char* names[] = {"id", "e1", "e2", "status", "flags", "psf_e1", "psf_e2", "snr", "radius", "R11", "R12", "R21",
                           "R22", "snr_1p", "radius_1p", "snr_1m", "radius_1m", "snr_2p", "radius_2p", "snr_2m",
                           "radius_2m"};
    for (int i = 0; i < 400; ++i) {
      const double r = 0.6 + 0.01 * (i % 97);  // 0.6 .. 1.56 px: about half below 1.0 x Gamma / 3.2
      const double values[] = {double(i), 0.01 * (i % 7) - 0.03, 0.02 - 0.005 * (i % 9), 0, 0, 0, 0.05, 20.0 + i % 11, r,
                               0.9, 0.01, -0.01, 0.85, 20, r + 0.004 * (i % 3), 20, r - 0.003 * (i % 5), 20,
                               r + 0.002 * (i % 4), 20, r - 0.001 * (i % 6)};
      for (int k = 0; k < 21; ++k) c[k].push_back(values[k]);
    }
    FitsFile f = FitsFile::create(path("mcal.fits"), true);
    f.write_empty_image();
    std::vector<FitsFile::OutputColumn> cols;
    for (int k = 0; k < 21; ++k) cols.push_back({names[k], k == 0 || k == 3 || k == 4, c[k]});
    f.write_table("RESULTS", cols);
    f.write_key("metacal_step", 0.01, "");
    f.write_key("metacal_gamma_fwhm", kGamma, "");
    f.close();
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

// --cut-size-ratio Q is the radius cut at Q x Gamma, on every image's own radius, with its
// selection response: the same report as --cut-radius Q x gamma; refused without --metacal.
TEST_F(MetricsCommand, ASizeRatioCutIsTheRadiusCutAtThatMultipleOfGamma) {
  write_metacal_table();
  const std::vector<std::string> set = {"--metacal", "--fit", path("mcal.fits"), "--truth", data("truth_0.fits")};
  // 0.30171875 x 3.2 = 0.9655 px, away from every radius (multiples of 0.001 px).
  const RunResult ratio = metrics(set + std::vector<std::string>{"--cut-size-ratio", "0.30171875"});
  ASSERT_EQ(ratio.exit_code, 0) << ratio.err;
  const std::string by_ratio = text_of(path("report.txt"));
  const RunResult radius = metrics(set + std::vector<std::string>{"--cut-radius", "0.9655"});
  ASSERT_EQ(radius.exit_code, 0) << radius.err;
  EXPECT_EQ(by_ratio, text_of(path("report.txt")));
  const RunResult none = metrics(set);
  EXPECT_NE(by_ratio, text_of(path("report.txt")));  // the cut does cut
  EXPECT_TRUE(Contains(by_ratio, "R_S = [[")) << by_ratio;
  const RunResult plain = metrics({"--fit", path("mcal.fits"), "--truth", data("truth_0.fits"), "--cut-size-ratio", "0.3"});
  EXPECT_EQ(plain.exit_code, 1);
  EXPECT_TRUE(Contains(plain.err, "--cut-size-ratio is a metacal cut")) << plain.err;
}

// --no-selection-response cuts on the noshear quantities alone: R_S reads exactly zero and the
// calibrated shear differs from the one with R_S; refused without --metacal.
TEST_F(MetricsCommand, NoSelectionResponseLeavesRsOut) {
  write_metacal_table();
  const std::vector<std::string> set = {"--metacal", "--fit", path("mcal.fits"), "--truth", data("truth_0.fits"),
                                        "--cut-radius", "0.9655"};
  ASSERT_EQ(metrics(set).exit_code, 0);
  const std::string with_rs = text_of(path("report.txt"));
  const RunResult without = metrics(set + std::vector<std::string>{"--no-selection-response"});
  ASSERT_EQ(without.exit_code, 0) << without.err;
  const std::string without_rs = text_of(path("report.txt"));
  EXPECT_FALSE(Contains(with_rs, "R_S = [[+0.0000 +0.0000] [+0.0000 +0.0000]]")) << with_rs;
  EXPECT_TRUE(Contains(without_rs, "R_S = [[+0.0000 +0.0000] [+0.0000 +0.0000]]")) << without_rs;
  EXPECT_NE(with_rs, without_rs);
  const RunResult plain = metrics({"--fit", path("mcal.fits"), "--truth", data("truth_0.fits"), "--no-selection-response"});
  EXPECT_EQ(plain.exit_code, 1);
  EXPECT_TRUE(Contains(plain.err, "--no-selection-response leaves metacal's R_S out")) << plain.err;
}

// A metacal cut that keeps objects on the noshear image but none on the sheared ones used to print
// <R> = 0, g = nan, m, c = NaN and Q = 0.0, write bare nan into the JSON and exit 0: now an error
// naming the cut and the empty selections.
TEST_F(MetricsCommand, AMetacalCutLeavingAShearedSelectionEmptyIsAnError) {
  write_metacal_table();  // noshear snr 20..30, every sheared image's 20
  const RunResult r = metrics({"--metacal", "--fit", path("mcal.fits"), "--truth", data("truth_0.fits"), "--cut-snr",
                               "25", "--json", path("m.json")});
  EXPECT_EQ(r.exit_code, 1) << r.err;
  EXPECT_TRUE(Contains(r.err, "mcal.fits[HDU 1 'RESULTS']: --cut-snr 25 keeps")) << r.err;
  EXPECT_TRUE(Contains(r.err, "but none on the 1p, 1m, 2p, 2m image's quantities")) << r.err;
  // Without R_S the sheared selections are the noshear one: a result.
  EXPECT_EQ(metrics({"--metacal", "--fit", path("mcal.fits"), "--truth", data("truth_0.fits"), "--cut-snr", "25",
                     "--no-selection-response"})
                .exit_code,
            0);
}

// Sets with one usable ring pair each: the bootstrap has nothing to resample, so the errors are
// n/a (JSON null), and so are m's and c's from a line through two such sets; they used to read
// "+- 0.0e+00".
TEST_F(MetricsCommand, ErrorsFromOneRingPairAreNotAvailable) {
  auto write_fit = [&](const std::string& file, double offset) {
    std::vector<double> id, e, st, zero(400, 0.0), psf(400, 0.05);
    for (int i = 0; i < 400; ++i) {
      id.push_back(i);
      e.push_back(offset + 0.01 * (i % 7));
      st.push_back(i < 2 ? 0 : 3);  // only the ring pair (0, 1) is usable
    }
    FitsFile f = FitsFile::create(file, true);
    f.write_empty_image();
    f.write_table("RESULTS", {{"id", true, id}, {"e1", false, e}, {"e2", false, e}, {"status", true, st},
                              {"flags", true, zero}, {"psf_e1", false, zero}, {"psf_e2", false, psf}});
  };
  write_fit(path("a.fits"), 0.0);
  write_fit(path("b.fits"), 0.01);
  const RunResult r = metrics({"--fit", path("a.fits"), "--truth", data("truth_0.fits"), "--fit", path("b.fits"),
                               "--truth", data("truth_1.fits"), "--json", path("m.json")});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const std::string out = text_of(path("report.txt")), json = text_of(path("m.json"));
  EXPECT_TRUE(Contains(out, "err n/a: set 0: 1 usable ring pair (a bootstrap error needs 2 or more)")) << out;
  EXPECT_TRUE(Contains(out, "m1 = ")) << out;
  EXPECT_FALSE(Contains(out, "+- 0.0e+00")) << out;
  EXPECT_TRUE(Contains(out, "+- n/a   c1 = ")) << out;
  EXPECT_TRUE(Contains(out, "m, c errors n/a: 2 sets, not all with a bootstrap error")) << out;
  EXPECT_TRUE(Contains(json, "\"err1\": null")) << json;
  EXPECT_TRUE(Contains(json, "\"m1_err\": null")) << json;
  EXPECT_FALSE(Contains(json, "nan")) << json;
}

// The same table given twice (the same path, or another name of the same file) would count its
// set twice: refused.
TEST_F(MetricsCommand, ARepeatedFitIsRefused) {
  write_metacal_table();
  const std::vector<std::string> twice = {"--fit", path("mcal.fits"), "--truth", data("truth_0.fits"), "--fit",
                                          path("mcal.fits"), "--truth", data("truth_1.fits")};
  const RunResult r = metrics(twice);
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_TRUE(Contains(r.err, "--fit '" + path("mcal.fits") + "' is given twice")) << r.err;
  std::filesystem::create_hard_link(path("mcal.fits"), path("again.fits"));
  const RunResult linked = metrics({"--fit", path("mcal.fits"), "--truth", data("truth_0.fits"), "--fit",
                                    path("again.fits"), "--truth", data("truth_1.fits")});
  EXPECT_EQ(linked.exit_code, 1);
  EXPECT_TRUE(Contains(linked.err, "--fit '" + path("again.fits") + "' is given twice")) << linked.err;
  // A one-value option given twice: the last used to win silently.
  const RunResult seeds = metrics({"--fit", path("mcal.fits"), "--truth", data("truth_0.fits"), "--seed", "1", "--seed",
                                   "2"});
  EXPECT_EQ(seeds.exit_code, 1);
  EXPECT_TRUE(Contains(seeds.err, "--seed is given twice")) << seeds.err;
}

// --json naming one of the inputs truncated it (the table was gone, exit 0): refused before any
// work, by path or by file identity; a directory is refused by name. A JSON replaces the old one
// whole.
TEST_F(MetricsCommand, TheJsonIsNeverAnInput) {
  write_metacal_table();
  const std::string table = text_of(path("mcal.fits"));
  std::filesystem::create_hard_link(path("mcal.fits"), path("link.fits"));
  for (const std::string& json : {path("mcal.fits"), path("link.fits")}) {
    const RunResult r = metrics({"--fit", path("mcal.fits"), "--truth", data("truth_0.fits"), "--json", json});
    EXPECT_EQ(r.exit_code, 1) << r.err;
    EXPECT_TRUE(Contains(r.err, "--json '" + json + "' is the --fit '" + path("mcal.fits") + "': writing it would destroy it"))
        << r.err;
    EXPECT_EQ(text_of(path("mcal.fits")), table);
  }
  const RunResult truth = metrics({"--fit", path("mcal.fits"), "--truth", data("truth_0.fits"), "--json", data("truth_0.fits")});
  EXPECT_EQ(truth.exit_code, 1);
  EXPECT_TRUE(Contains(truth.err, "is the --truth")) << truth.err;
  const RunResult dir = metrics({"--fit", path("mcal.fits"), "--truth", data("truth_0.fits"), "--json", path("")});
  EXPECT_EQ(dir.exit_code, 1);
  EXPECT_TRUE(Contains(dir.err, "is a directory; name the file to write")) << dir.err;
  {
    std::ofstream old(path("m.json"));
    old << std::string(100000, '#');  // longer than the new JSON: replaced whole, not overwritten in place
  }
  ASSERT_EQ(metrics({"--fit", path("mcal.fits"), "--truth", data("truth_0.fits"), "--json", path("m.json")}).exit_code, 0);
  const std::string json = text_of(path("m.json"));
  EXPECT_EQ(json.find('#'), std::string::npos);
  EXPECT_EQ(json.substr(json.size() - 2), "}\n");
}

// The same for metrics --metadetect: its --json naming the catalogue it reads is refused before
// the catalogue is read (it was truncated once the figures were computed).
TEST_F(MetricsCommand, TheMetadetectJsonIsNeverAnInput) {
  { std::ofstream(path("md.fits")) << "a catalogue"; }
  const RunResult r = metrics({"--metadetect", path("md.fits"), "--json", path("md.fits")});
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_TRUE(Contains(r.err, "--json '" + path("md.fits") + "' is the --metadetect '" + path("md.fits") +
                                  "': writing it would destroy it"))
      << r.err;
  EXPECT_EQ(text_of(path("md.fits")), "a catalogue");
}

// A status or flag that no fit writes (NaN, 2.5, a status past the last), or an e no fit gives, is
// a damaged table, named by file, column and row; the integers used to be cast (undefined for NaN)
// and the row silently kept or dropped.
TEST_F(MetricsCommand, IntegersNoFitWritesAreNamed) {
  auto write_fit = [&](const std::string& file, const std::string& column, double bad) {
    std::vector<double> id, e, st(400, 0.0), flags(400, 0.0), psf(400, 0.05);
    for (int i = 0; i < 400; ++i) {
      id.push_back(i);
      e.push_back(0.01 * (i % 7));
    }
    (column == "status" ? st : column == "flags" ? flags : e)[17] = bad;
    FitsFile f = FitsFile::create(file, true);
    f.write_empty_image();
    f.write_table("RESULTS", {{"id", true, id}, {"e1", false, e}, {"e2", false, e}, {"status", false, st},
                              {"flags", false, flags}, {"psf_e1", false, psf}, {"psf_e2", false, psf}});
  };
  for (const auto& [column, bad, text] : {std::tuple{"status", double(NAN), "nan"}, std::tuple{"status", 2.5, "2.5"},
                                          std::tuple{"status", 99.0, "99"}, std::tuple{"flags", -1.0, "-1"},
                                          std::tuple{"flags", 1e300, "1e+300"}}) {
    write_fit(path("bad.fits"), column, bad);
    const RunResult r = metrics({"--fit", path("bad.fits"), "--truth", data("truth_0.fits")});
    EXPECT_EQ(r.exit_code, 1) << column << " " << text;
    EXPECT_TRUE(Contains(r.err, "bad.fits[HDU 1 'RESULTS']: column '" + std::string(column) + "' row 17 = " + text +
                                    " is not an integer in ["))
        << r.err;
  }
  // An e of -1e308 made the set's mean overflow: g2 = -inf printed as a result, exit 0.
  write_fit(path("bad.fits"), "e1", -1e308);
  const RunResult r = metrics({"--fit", path("bad.fits"), "--truth", data("truth_0.fits")});
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_TRUE(Contains(r.err, "bad.fits[HDU 1 'RESULTS']: column 'e1' row 17 = -1e+308 is not an ellipticity (|e| <= 10)"))
      << r.err;
}

// The PSF frame is the first row's PSF e: a damaged one (psf_e2 = -inf) was printed as the frame,
// "PSF frame (e = 0.000, -inf)" (found by fuzz/fuzz_metrics_report.py); now it is not taken.
TEST_F(MetricsCommand, ADamagedPsfEllipticityIsNotTheFrame) {
  auto write_fit = [&](const std::string& file, double psf_e2) {
    std::vector<double> id, e, zero(400, 0.0), psf(400, 0.05);
    for (int i = 0; i < 400; ++i) id.push_back(i), e.push_back(0.01 * (i % 7));
    psf[0] = psf_e2;
    FitsFile f = FitsFile::create(file, true);
    f.write_empty_image();
    f.write_table("RESULTS", {{"id", true, id}, {"e1", false, e}, {"e2", false, e}, {"status", true, zero},
                              {"flags", true, zero}, {"psf_e1", false, zero}, {"psf_e2", false, psf}});
  };
  write_fit(path("a.fits"), 0.05);
  write_fit(path("b.fits"), -INFINITY);
  const RunResult r = metrics({"--fit", path("a.fits"), "--truth", data("truth_0.fits"), "--fit", path("b.fits"),
                               "--truth", data("truth_1.fits")});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const std::string out = text_of(path("report.txt"));
  EXPECT_TRUE(Contains(out, "PSF frame (e = 0.000, 0.050)")) << out;  // set 0's, the last finite one
  EXPECT_FALSE(Contains(out, "inf")) << out;
}

// Metacal's R calibrates the noshear e (e1, e2); applied to calibrate apply's e1_cal, e2_cal it
// calibrated twice, with only calibrate apply's warning: refused. The same columns by another case
// are e1, e2.
TEST_F(MetricsCommand, MetacalCalibratesOnlyTheNoshearE) {
  write_metacal_table();
  const RunResult r = metrics({"--metacal", "--fit", path("mcal.fits"), "--truth", data("truth_0.fits"), "--e-columns",
                               "e1_cal,e2_cal"});
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_TRUE(Contains(r.err, "--metacal with --e-columns 'e1_cal,e2_cal': metacal's R is the response of the noshear e"))
      << r.err;
  EXPECT_EQ(metrics({"--metacal", "--fit", path("mcal.fits"), "--truth", data("truth_0.fits"), "--e-columns", "E1,E2"})
                .exit_code,
            0);
}

}  // namespace
