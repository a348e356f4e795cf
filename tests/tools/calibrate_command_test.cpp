// End-to-end tests of `stampede calibrate build | apply` on a small grid: the table's contents,
// kill -9 then --resume equal to an uninterrupted build, the applied corrections against the
// engine's model, and bad input named in the error.
#include <gtest/gtest.h>
#include <signal.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <map>
#include <string>
#include <thread>
#include <vector>

#include "engine/calibration/noise_bias.hpp"
#include "io/calibration_table.hpp"
#include "io/fits_file.hpp"
#include "support/command_runner.hpp"
#include "support/scratch_dir.hpp"

namespace fs = std::filesystem;

namespace {

using namespace stampede;
using stampede::io::FitsFile;
using stampede::testing::finish;
using stampede::testing::RunResult;
using stampede::testing::spawn;

// 2 radii x 2 fractions x 2 axes x 6 e = 48 points x 3 noise pairs = 288 fits of 25-pixel stamps.
const std::vector<std::string> kSmallBuild = {"--radii", "1.2,2",   "--bulge-fractions", "0,1",        "--e-steps", "6",
                                              "--e-max", "0.5",     "--realisations",    "3",          "--set",
                                              "stamp_size=25",      "--set",             "noise_sigma=1", "--set",
                                              "psf_e2=0.05",        "--threads",         "2"};

class CalibrateCommand : public ::testing::Test {
 protected:
  std::string path(const std::string& name) const { return scratch.path(name); }
  RunResult run(std::vector<std::string> args) {
    return finish(spawn(args, path("stderr.txt"), "calibrate"), path("stderr.txt"));
  }
  RunResult build(const std::string& out, std::vector<std::string> extra = {}) {
    std::vector<std::string> args = {"build", "-o", out};
    args.insert(args.end(), kSmallBuild.begin(), kSmallBuild.end());
    args.insert(args.end(), extra.begin(), extra.end());
    return run(args);
  }
  // A fit-like catalogue with the columns apply reads (and one it must carry along), and the header
  // keys of the fit method (renderer "" = none recorded).
  void write_catalogue(const std::string& file, const std::string& renderer = "exact",
                       const std::string& surrogate = "true", double snr_scale = 1) {
    std::vector<double> id, e1, e2, snr, pe1, pe2, radius, bf, df, status, flags, extra;
    for (int i = 0; i < 40; ++i) {
      id.push_back(i);
      e1.push_back(0.4 * std::sin(i * 0.7));
      e2.push_back(0.3 * std::cos(i * 1.3));
      snr.push_back(i == 5 ? NAN : snr_scale * (10.0 + i));
      pe1.push_back(i % 2 ? 0.0 : 0.03);
      pe2.push_back(0.05);
      radius.push_back(1.0 + 0.03 * i);
      bf.push_back(10.0 * (i % 5));
      df.push_back(40.0 - 10.0 * (i % 5));
      status.push_back(i == 7 ? 1 : 0);
      flags.push_back(0);
      extra.push_back(100 + i);
    }
    FitsFile f = FitsFile::create(file, false);
    f.write_empty_image();
    f.write_table("RESULTS", {{"id", true, id},         {"e1", false, e1},         {"e2", false, e2},
                              {"snr", false, snr},      {"psf_e1", false, pe1},    {"psf_e2", false, pe2},
                              {"radius", false, radius}, {"bulge_flux", false, bf}, {"disc_flux", false, df},
                              {"status", true, status}, {"flags", true, flags},    {"extra", false, extra}});
    if (renderer.empty()) return;
    f.write_key("RENDERER", renderer, "");
    f.write_key("EXACT_SURROGATE", surrogate, "");
    f.write_key("PROJECT_AMPLITUDES", std::string("true"), "");
  }
  stampede::testing::ScratchDir scratch{std::string("stampede_calibrate_") +
                                          ::testing::UnitTest::GetInstance()->current_test_info()->name() + "_"};
};

long long header_long(const std::string& file, const std::string& key) {
  FitsFile f = FitsFile::open_read(file);
  f.move_to("RESULTS");
  return f.key_long(key);
}

std::vector<double> column(const std::string& file, const std::string& hdu, const std::string& name) {
  FitsFile f = FitsFile::open_read(file);
  f.move_to(hdu);
  return f.read_column(name);
}

TEST_F(CalibrateCommand, BuildWritesTheGridAndApplyCorrectsByTheModel) {
  const RunResult b = build(path("cal.fits"));
  ASSERT_EQ(b.exit_code, 0) << b.err;
  EXPECT_NE(b.err.find("288 fits"), std::string::npos) << b.err;
  EXPECT_FALSE(fs::exists(path("cal.fits.partial")));
  const CalibrationTable t = io::read_calibration_table(path("cal.fits"));
  ASSERT_EQ(t.points.size(), 48u);
  ASSERT_EQ(t.curves.size(), 16u);
  EXPECT_EQ(t.grid.stamp_size, 25);
  EXPECT_EQ(t.grid.psf.moffat.e2, 0.05);
  EXPECT_EQ(t.grid.radii, (std::vector<double>{1.2, 2.0}));
  int pairs = 0;
  for (const PointBias& p : t.biases) {
    pairs += p.pairs_used + p.pairs_failed;
    EXPECT_LT(std::abs(p.bias[0]), 0.3);  // a fit that went astray would show here
  }
  EXPECT_EQ(pairs, 48 * 3);
  bool has_noise_sigma = false;
  for (const auto& [k, v] : t.config) has_noise_sigma |= k == "noise_sigma" && v == "1";
  EXPECT_TRUE(has_noise_sigma);

  // Population mode: the deep catalogue's usable rows give m_hat; every row gets it scaled.
  write_catalogue(path("science.fits"));
  write_catalogue(path("deep.fits"));
  RunResult a = run({"apply", path("science.fits"), "--calibration", path("cal.fits"), "--deep", path("deep.fits"), "-o",
                     path("out.fits")});
  ASSERT_EQ(a.exit_code, 0) << a.err;
  const NoiseBiasModel model(t);
  PopulationBias pop(model);
  const auto e1 = column(path("science.fits"), "RESULTS", "e1"), e2 = column(path("science.fits"), "RESULTS", "e2"),
             snr = column(path("science.fits"), "RESULTS", "snr"), radius = column(path("science.fits"), "RESULTS", "radius"),
             bf = column(path("science.fits"), "RESULTS", "bulge_flux"),
             df = column(path("science.fits"), "RESULTS", "disc_flux"), pe1 = column(path("science.fits"), "RESULTS", "psf_e1");
  for (std::size_t i = 0; i < e1.size(); ++i)
    if (i != 7) pop.add({radius[i], bf[i] / (bf[i] + df[i]), std::hypot(e1[i], e2[i])});
  const Bias mean = pop.mean();
  FitsFile out = FitsFile::open_read(path("out.fits"));
  out.move_to("RESULTS");
  EXPECT_EQ(out.key_string("NBCMODE"), "population");
  EXPECT_EQ(out.key_long("NBCNDEEP"), 39);
  EXPECT_NEAR(out.key_double("NBCM"), mean.m, 1e-15);
  EXPECT_EQ(out.read_column("extra"), column(path("science.fits"), "RESULTS", "extra"));  // carried along
  const auto e1c = out.read_column("e1_cal"), e2c = out.read_column("e2_cal"), m = out.read_column("nbc_m"),
             c1 = out.read_column("nbc_c1");
  for (std::size_t i = 0; i < e1.size(); ++i) {
    if (i == 5) {  // no S/N: no calibration
      EXPECT_TRUE(std::isnan(e1c[i]) && std::isnan(m[i]));
      continue;
    }
    const Bias k = object_correction(mean, 20.0, {0.0, 0.05}, snr[i], {pe1[i], 0.05});
    EXPECT_NEAR(m[i], mean.m * (20 / snr[i]) * (20 / snr[i]), 1e-15);
    EXPECT_NEAR(c1[i], k.c1, 1e-15);
    EXPECT_NEAR(e1c[i], (e1[i] - k.c1) / (1 + k.m), 1e-15);
    EXPECT_NEAR(e2c[i], (e2[i] - k.c2) / (1 + k.m), 1e-15);
  }

  // Per-object mode: each row's own properties.
  a = run({"apply", path("science.fits"), "--calibration", path("cal.fits"), "--per-object", "-o", path("obj.fits")});
  ASSERT_EQ(a.exit_code, 0) << a.err;
  const auto m_obj = column(path("obj.fits"), "RESULTS", "nbc_m");
  for (int i : {0, 11, 30}) {
    const Bias own = model.at({radius[i], bf[i] / (bf[i] + df[i]), std::hypot(e1[i], e2[i])});
    EXPECT_NEAR(m_obj[i], own.m * (20 / snr[i]) * (20 / snr[i]), 1e-15);
  }
  // Rows outside the grid (radius outside [1.2, 2]) are counted and said: their bias is the edge's.
  long long outside = 0;
  for (double r : radius) outside += r < 1.2 || r > 2.0;
  ASSERT_GT(outside, 0);
  EXPECT_EQ(header_long(path("obj.fits"), "NBCNCLMP"), outside);
  EXPECT_NE(a.err.find("warning: " + std::to_string(outside) + " of 40 rows lie outside the calibration's grid"),
            std::string::npos) << a.err;
  EXPECT_EQ(a.err.find("S/N below"), std::string::npos) << a.err;  // every row's S/N is >= 10, half of 20
  // Rows far below the calibration's S/N get its bias scaled (S/N)^-2 beyond its reach: said, counted.
  write_catalogue(path("faint.fits"), "exact", "true", 0.25);
  a = run({"apply", path("faint.fits"), "--calibration", path("cal.fits"), "--per-object", "-o", path("faint_cal.fits")});
  ASSERT_EQ(a.exit_code, 0) << a.err;
  EXPECT_NE(a.err.find("warning: 29 of 39 rows (74.4%) have S/N below 10, half the calibration's 20"), std::string::npos)
      << a.err;
  EXPECT_EQ(header_long(path("faint_cal.fits"), "NBCNLOW"), 29);
  // The output is not replaced silently.
  a = run({"apply", path("science.fits"), "--calibration", path("cal.fits"), "--per-object", "-o", path("obj.fits")});
  EXPECT_EQ(a.exit_code, 1);
  EXPECT_NE(a.err.find("--overwrite"), std::string::npos) << a.err;
}

// Issue 29: a calibration holds for the estimator that built it. The table records the renderer
// (renderer = auto as it resolved) and the solver options; apply refuses another, naming both.
TEST_F(CalibrateCommand, ATableIsAppliedOnlyWithTheRendererAndSolverThatBuiltIt) {
  ASSERT_EQ(build(path("cal.fits")).exit_code, 0);
  std::map<std::string, std::string> config;
  for (const auto& [k, v] : io::read_calibration_table(path("cal.fits")).config) config[k] = v;
  EXPECT_EQ(config["renderer"], "exact");  // auto, resolved for the Moffat PSF
  EXPECT_EQ(config["exact_surrogate"], "true");
  auto apply = [&](const std::string& science, const std::string& calibration) {
    return run({"apply", science, "--calibration", calibration, "--per-object", "-o", path("out.fits"), "--overwrite"});
  };
  write_catalogue(path("same.fits"));
  RunResult r = apply(path("same.fits"), path("cal.fits"));
  EXPECT_EQ(r.exit_code, 0) << r.err;
  write_catalogue(path("upsampled.fits"), "upsampled");
  r = apply(path("upsampled.fits"), path("cal.fits"));
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_NE(r.err.find("cal.fits was built with renderer = exact, " + path("upsampled.fits") +
                       " fitted with renderer = upsampled: a calibration holds only for the renderer and solver"),
            std::string::npos) << r.err;
  write_catalogue(path("no_surrogate.fits"), "exact", "false");
  r = apply(path("no_surrogate.fits"), path("cal.fits"));
  EXPECT_NE(r.err.find("built with exact_surrogate = true, " + path("no_surrogate.fits") +
                       " fitted with exact_surrogate = false"), std::string::npos) << r.err;
  write_catalogue(path("unrecorded.fits"), "");
  r = apply(path("unrecorded.fits"), path("cal.fits"));
  EXPECT_NE(r.err.find("unrecorded.fits does not record the renderer that fitted it"), std::string::npos) << r.err;
  {  // a table from before tables recorded their renderer
    CalibrationTable t = io::read_calibration_table(path("cal.fits"));
    std::erase_if(t.config, [](const auto& kv) { return kv.first == "renderer"; });
    io::write_calibration_table(path("old.fits"), t, false);
  }
  r = apply(path("same.fits"), path("old.fits"));
  EXPECT_NE(r.err.find("old.fits does not record the renderer it was built with (an older table); rebuild"),
            std::string::npos) << r.err;
}

// Issue 44: every table committed in docs/calibration/ was built with the default fit (renderer =
// auto, resolved to exact for its Moffat PSF): apply accepts it on a default-fit catalogue and
// refuses it on an upsampled-renderer one, naming both renderers.
TEST_F(CalibrateCommand, EveryCommittedTableIsAppliedToTheDefaultFitOnly) {
  std::vector<std::string> tables;
  for (const auto& entry : fs::directory_iterator(STAMPEDE_CALIBRATION_DIR)) {
    const std::string name = entry.path().filename().string();
    if (name.starts_with("calibration_") && name.ends_with(".fits")) tables.push_back(entry.path().string());
  }
  std::sort(tables.begin(), tables.end());
  ASSERT_EQ(tables.size(), 7u);  // the seven tables docs/calibration/README.md lists
  write_catalogue(path("default.fits"));
  write_catalogue(path("upsampled.fits"), "upsampled");
  for (const std::string& table : tables) {
    std::map<std::string, std::string> config;
    for (const auto& [k, v] : io::read_calibration_table(table).config) config[k] = v;
    EXPECT_EQ(config["renderer"], "exact") << table;
    EXPECT_EQ(config["exact_surrogate"], "true") << table;
    EXPECT_EQ(config["project_amplitudes"], "true") << table;
    for (const std::string mode : {"--per-object", "--deep"}) {
      std::vector<std::string> args = {"apply", path("default.fits"), "--calibration", table, "-o", path("out.fits"),
                                       "--overwrite", "--quiet", mode};
      if (mode == "--deep") args.push_back(path("default.fits"));
      RunResult r = run(args);
      EXPECT_EQ(r.exit_code, 0) << table << " " << mode << ": " << r.err;
      EXPECT_EQ(column(path("out.fits"), "RESULTS", "e1_cal").size(), 40u) << table;
      args[1] = path("upsampled.fits");
      r = run(args);
      EXPECT_EQ(r.exit_code, 1) << table;
      EXPECT_NE(r.err.find(table + " was built with renderer = exact, " + path("upsampled.fits") +
                           " fitted with renderer = upsampled"),
                std::string::npos)
          << r.err;
    }
  }
}

TEST_F(CalibrateCommand, KillNineThenResumeEqualsUninterruptedBuild) {
  ASSERT_EQ(build(path("full.fits"), {"--quiet"}).exit_code, 0);
  const std::string out = path("resumed.fits");
  std::vector<std::string> args = {"build", "-o", out, "--quiet"};
  args.insert(args.end(), kSmallBuild.begin(), kSmallBuild.end());
  const pid_t pid = spawn(args, path("stderr.txt"), "calibrate");
  // Wait until a few points are committed, then kill without warning.
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(120);
  auto lines = [&] {
    std::ifstream in(out + ".partial");
    int n = 0;
    for (std::string l; std::getline(in, l);) ++n;
    return n;
  };
  while (lines() < 6 && std::chrono::steady_clock::now() < deadline)
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  ASSERT_EQ(kill(pid, SIGKILL), 0);
  const RunResult killed = finish(pid, path("stderr.txt"));
  ASSERT_EQ(killed.exit_code, 128 + SIGKILL) << "the build finished before it could be killed";
  ASSERT_FALSE(fs::exists(out));
  args.push_back("--resume");
  const RunResult resumed = run(args);
  ASSERT_EQ(resumed.exit_code, 0) << resumed.err;
  for (const char* name : {"bias1", "bias1_err", "bias2", "bias2_err", "pairs_used"})
    EXPECT_EQ(column(out, "POINTS", name), column(path("full.fits"), "POINTS", name)) << name;
  for (const char* name : {"a0", "a1", "a2", "a3"})
    EXPECT_EQ(column(out, "CURVES", name), column(path("full.fits"), "CURVES", name)) << name;
  // A progress file of another build (other options) is refused, not mixed in.
  {
    std::ofstream fake(out + ".partial");
    fake << "# stampede calibrate build 0123456789abcdef\n";
  }
  const RunResult other = run(args);
  EXPECT_NE(other.exit_code, 0);
  EXPECT_NE(other.err.find("different build"), std::string::npos) << other.err;
}

TEST_F(CalibrateCommand, BadInputIsNamed) {
  auto error = [&](std::vector<std::string> args) {
    const RunResult r = run(args);
    EXPECT_NE(r.exit_code, 0);
    return r.err;
  };
  EXPECT_NE(error({"build", "-o", path("c.fits")}).find("noise_sigma"), std::string::npos);
  EXPECT_NE(error({"build", "-o", path("c.fits"), "--set", "noise_sigma=1", "--set", "psf_input=image"}).find("psf_input"),
            std::string::npos);
  EXPECT_NE(error({"build", "-o", path("c.fits"), "--radii", "2,x"}).find("--radii"), std::string::npos);
  EXPECT_NE(error({"build", "-o", path("c.fits"), "--set", "noise_sigma=1", "--radii", "3,1"}).find("--radii 3,1"),
            std::string::npos);
  EXPECT_NE(error({"build", "-o", path("c.fits"), "--e-steps", "2"}).find("--e-steps"), std::string::npos);
  EXPECT_NE(error({"build", "--bogus"}).find("--bogus"), std::string::npos);
  EXPECT_NE(error({"frobnicate"}).find("frobnicate"), std::string::npos);
  write_catalogue(path("science.fits"));
  EXPECT_NE(error({"apply", path("science.fits"), "--calibration", path("science.fits"), "-o", path("o.fits")})
                .find("--per-object"),
            std::string::npos);
  const std::string not_cal = error(
      {"apply", path("science.fits"), "--calibration", path("science.fits"), "--per-object", "-o", path("o.fits")});
  EXPECT_NE(not_cal.find("science.fits"), std::string::npos) << not_cal;
  EXPECT_NE(not_cal.find("CALIBVER"), std::string::npos) << not_cal;
  EXPECT_FALSE(fs::exists(path("o.fits")));
  // A catalogue without the columns apply needs: the file and the column are named.
  {
    FitsFile f = FitsFile::create(path("bare.fits"), false);
    f.write_empty_image();
    f.write_table("RESULTS", {{"id", true, {0, 1}}, {"e1", false, {0.1, 0.2}}, {"e2", false, {0.0, 0.1}}});
  }
  {  // a valid calibration file, written directly: flat bias curves over the default grid
    CalibrationTable t;
    t.points = CalibrationGrid(t.grid).points();
    t.biases.resize(t.points.size());
    for (double r : t.grid.radii)
      for (double f : t.grid.bulge_fractions)
        for (int k = 0; k < 4; ++k) {
          BiasCurve c;
          c.radius = r;
          c.bulge_fraction = f;
          c.axis = k < 2 ? BiasAxis::kE1 : BiasAxis::kE2;
          c.component = k % 2;
          c.coefficients = {0.0, 0.02, 0.0, 0.0};
          t.curves.push_back(c);
        }
    io::write_calibration_table(path("cal.fits"), t, false);
  }
  const std::string bare = error({"apply", path("bare.fits"), "--calibration", path("cal.fits"), "--per-object", "-o",
                                  path("o.fits")});
  EXPECT_NE(bare.find("bare.fits"), std::string::npos) << bare;
  EXPECT_NE(bare.find("'snr'"), std::string::npos) << bare;
}

}  // namespace
