// FitRun over a small grid: the summary's counts match the table, its brief report is the line
// `stampede fit` prints, and two runs in one process with different thread counts give identical
// tables and leave no process-wide threading state behind. Outputs: locked for the run's life
// (a second run on them is refused), not replaced without overwrite, and a run that fails with an
// error leaves no partial files; one stopped (FitRunOptions::stop) leaves them for resume.
#include <gtest/gtest.h>
#include <tbb/global_control.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <regex>
#include <stdexcept>
#include <string>
#include <vector>

#include "app/fit_run.hpp"
#include "io/durable_file.hpp"
#include "io/fits_file.hpp"
#include "io/output_lock.hpp"
#include "io/psf_keys.hpp"
#include "support/command_runner.hpp"
#include "support/error_assertions.hpp"
#include "support/scratch_dir.hpp"

namespace {

using namespace stampede;

constexpr int kNx = 6, kNy = 2, kStamp = 39;

// The first kNx x kNy stamps of the GREAT08-mini S/N 40 set as a grid of their own, with the set's
// PSF record; stamp 0 has a NaN pixel and stamp 1 is empty, so the table has several statuses.
void write_small_grid(const std::string& path) {
  io::FitsFile in = io::FitsFile::open_read(std::string(STAMPEDE_DATA_DIR) + "/galsim-great08-mini/snr40/set_0.fits");
  const auto shape = in.image_shape();
  const std::vector<double> all = in.read_image();
  std::vector<double> part;
  for (long y = 0; y < kNy * kStamp; ++y)
    part.insert(part.end(), all.begin() + y * shape.nx, all.begin() + y * shape.nx + kNx * kStamp);
  part[kStamp / 2 * kNx * kStamp + kStamp / 2] = NAN;  // stamp 0: a bad pixel
  for (int y = 0; y < kStamp; ++y)                    // stamp 1: no flux
    std::fill_n(part.begin() + y * kNx * kStamp + kStamp, kStamp, 0.0);
  io::FitsFile out = io::FitsFile::create(path, true);
  out.write_image(kNx * kStamp, kNy * kStamp, part);
  out.write_key("STAMPSZ", kStamp, "stamp size");
  io::write_psf_keys(out, io::read_psf_keys(in));
}

// A cheap configuration: the results need only be identical.
const std::vector<std::string> kSets = {"psf_beta=3", "psf_fwhm=2.85", "psf_e2=0.05", "noise_sigma=1",
                                        "upsampling=2", "n_central_pixels_to_upsample=1", "padding=0",
                                        "minimizer_max_iterations=10", "batch_size=5"};

class FitRunTest : public ::testing::Test {
 protected:
  void SetUp() override { write_small_grid(input); }
  app::FitRunOptions options(const std::string& output, int threads) const {
    app::FitRunOptions o;
    o.input = input;
    o.output = output;
    o.threads = threads;
    for (const auto& s : kSets) app::apply_set(o.config, s);
    return o;
  }
  stampede::testing::ScratchDir scratch{"stampede_fit_run_"};
  std::string input = scratch.path("grid.fits");
};

std::vector<double> column(const std::string& file, const std::string& name) {
  io::FitsFile f = io::FitsFile::open_read(file);
  f.move_to("RESULTS");
  return f.read_column(name);
}

bool same_bits(double a, double b) { return (std::isnan(a) && std::isnan(b)) || std::memcmp(&a, &b, sizeof a) == 0; }

TEST_F(FitRunTest, SummaryCountsMatchTheTable) {
  const std::string out = scratch.path("out.fits");
  long long rows_seen = 0;
  app::FitRunOptions o = options(out, 2);
  o.on_rows = [&](std::span<const ObjectRecord> rows) {
    for (const ObjectRecord& r : rows) EXPECT_EQ(r.id, rows_seen++);  // input order
  };
  const app::RunSummary s = app::FitRun(o).run();
  EXPECT_EQ(s.objects, kNx * kNy);
  EXPECT_EQ(rows_seen, kNx * kNy);
  EXPECT_EQ(s.resumed, 0);
  EXPECT_EQ(s.batches, (kNx * kNy + 4) / 5);
  EXPECT_EQ(s.threads, 2);
  EXPECT_EQ(s.output, out);
  std::array<long long, kFitStatusCount> from_table{};
  for (double st : column(out, "status")) ++from_table[static_cast<int>(st)];
  EXPECT_EQ(s.by_status, from_table);
  int statuses = 0;
  for (long long c : from_table) statuses += c > 0;
  EXPECT_GE(statuses, 3) << s.FullReport();  // the comparison covers more than one status
  EXPECT_GT(s.setup_seconds, 0);
  EXPECT_GT(s.pipeline_seconds, 0);
  EXPECT_GE(s.total_seconds, s.setup_seconds + s.pipeline_seconds + s.finish_seconds);
}

TEST_F(FitRunTest, BriefReportIsTheLineTheCommandPrints) {
  const app::RunSummary s = app::FitRun(options(scratch.path("lib.fits"), 2)).run();
  // The same output again: replaced only because --overwrite says so.
  std::vector<std::string> args = {input, "-o", scratch.path("lib.fits"), "--threads", "2", "--overwrite"};
  for (const auto& set : kSets) args.insert(args.end(), {"--set", set});
  const std::string err = scratch.path("err.txt");
  const stampede::testing::RunResult r = stampede::testing::finish(stampede::testing::spawn(args, err), err);
  ASSERT_EQ(r.exit_code, 0) << r.err;
  // The timings differ between two runs; everything else must be the same text.
  const std::regex timing("in [0-9.]+ s, [0-9.]+ objects/s");
  EXPECT_EQ(std::regex_replace(r.err, timing, "in T s, R objects/s"),
            std::regex_replace(s.BriefReport(), timing, "in T s, R objects/s") + "\n");
}

TEST_F(FitRunTest, TwoRunsInOneProcessWithDifferentThreadsAreIdentical) {
  const std::size_t parallelism = tbb::global_control::active_value(tbb::global_control::max_allowed_parallelism);
  std::vector<ObjectRecord> rows[2];
  const int threads[2] = {3, 1};
  for (int k = 0; k < 2; ++k) {
    app::FitRunOptions o = options(scratch.path("t" + std::to_string(threads[k]) + ".fits"), threads[k]);
    o.on_rows = [&, k](std::span<const ObjectRecord> batch) { rows[k].insert(rows[k].end(), batch.begin(), batch.end()); };
    const app::RunSummary s = app::FitRun(o).run();
    EXPECT_EQ(s.threads, threads[k]);
    // No process-wide limit set or left behind by the run.
    EXPECT_EQ(tbb::global_control::active_value(tbb::global_control::max_allowed_parallelism), parallelism);
  }
  ASSERT_EQ(rows[0].size(), static_cast<std::size_t>(kNx * kNy));
  ASSERT_EQ(rows[1].size(), rows[0].size());
  for (std::size_t i = 0; i < rows[0].size(); ++i) {
    const ObjectRecord &a = rows[0][i], &b = rows[1][i];
    EXPECT_EQ(a.id, b.id);
    EXPECT_EQ(a.fit.status, b.fit.status);
    EXPECT_EQ(a.flags, b.flags);
    EXPECT_EQ(a.fit.iterations, b.fit.iterations);
    for (int p = 0; p < kNumParams; ++p) EXPECT_TRUE(same_bits(a.fit.params[p], b.fit.params[p])) << i << " " << p;
    EXPECT_TRUE(same_bits(a.fit.chi2, b.fit.chi2)) << i;
  }
  for (const char* name : {"e1", "e2", "radius", "chi2", "status", "flags", "snr"}) {
    const auto x = column(scratch.path("t3.fits"), name), y = column(scratch.path("t1.fits"), name);
    ASSERT_EQ(x.size(), y.size());
    for (std::size_t i = 0; i < x.size(); ++i) EXPECT_TRUE(same_bits(x[i], y[i])) << name << " row " << i;
  }
}

// A metacal run: the table carries the metacal columns, rows are bitwise identical for any thread
// count (the fixnoise fields are keyed by object id), and the stamps the fitter refuses (a NaN
// pixel, an empty stamp) are refused here too rather than fitted as fixnoise's noise.
TEST_F(FitRunTest, MetacalRunsAreIdenticalForAnyThreadCount) {
  std::vector<ObjectRecord> rows[2];
  const int threads[2] = {2, 1};
  for (int k = 0; k < 2; ++k) {
    app::FitRunOptions o = options(scratch.path("m" + std::to_string(threads[k]) + ".fits"), threads[k]);
    app::apply_set(o.config, "renderer=exact");
    app::apply_set(o.config, "metacal=true");
    o.on_rows = [&, k](std::span<const ObjectRecord> batch) { rows[k].insert(rows[k].end(), batch.begin(), batch.end()); };
    app::FitRun(o).run();
  }
  ASSERT_EQ(rows[0].size(), static_cast<std::size_t>(kNx * kNy));
  ASSERT_EQ(rows[1].size(), rows[0].size());
  EXPECT_EQ(rows[0][0].fit.status, FitStatus::kBadPixels);
  EXPECT_EQ(rows[0][1].fit.status, FitStatus::kNoData);
  EXPECT_TRUE(rows[0][1].flags & kFlagMetacalFailure);
  int with_response = 0;
  for (std::size_t i = 0; i < rows[0].size(); ++i) {
    const ObjectRecord &a = rows[0][i], &b = rows[1][i];
    EXPECT_EQ(a.flags, b.flags);
    for (int p = 0; p < kNumParams; ++p) EXPECT_TRUE(same_bits(a.fit.params[p], b.fit.params[p])) << i << " " << p;
    for (const auto& [x, y] : {std::pair{a.metacal.r11, b.metacal.r11}, std::pair{a.metacal.r22, b.metacal.r22},
                               std::pair{a.metacal.e1[3], b.metacal.e1[3]}, std::pair{a.metacal.snr[0], b.metacal.snr[0]}})
      EXPECT_TRUE(same_bits(x, y)) << i;
    if (usable_for_shear(a.fit.status, a.flags)) {
      ++with_response;
      // A galaxy's response: positive; the default wmom's is below a fit's ~1 (its weight is
      // PSF-sized, so the measured ellipticity is diluted by the round Gamma).
      EXPECT_GT(a.metacal.r11, 0.05) << i;
      EXPECT_LT(a.metacal.r11, 2.0) << i;
    }
  }
  EXPECT_GE(with_response, 6);
  const auto r11 = column(scratch.path("m2.fits"), "R11"), radius = column(scratch.path("m1.fits"), "radius_2m");
  ASSERT_EQ(r11.size(), rows[0].size());
  for (std::size_t i = 0; i < r11.size(); ++i) {
    EXPECT_TRUE(same_bits(r11[i], rows[0][i].metacal.r11)) << i;
    EXPECT_TRUE(same_bits(radius[i], rows[1][i].metacal.radius[3])) << i;
  }
}

// A reconvolution PSF metacal cannot use (not wider than the PSF sheared, in every direction) is
// an error before any fitting, not a table of PSF failures; the one used is in the header.
TEST_F(FitRunTest, AMetacalReconvolutionPsfTooNarrowIsRefusedUpFront) {
  app::FitRunOptions o = options(scratch.path("narrow.fits"), 1);
  app::apply_set(o.config, "metacal=true");
  app::apply_set(o.config, "metacal_reconvolution_psf=moffat");
  app::apply_set(o.config, "metacal_psf_dilation=1");
  const std::string message = stampede::testing::error_of<io::ConfigError>([&] { app::FitRun(o).run(); });
  EXPECT_NE(message.find("metacal_psf_dilation = 1: metacal: the reconvolution PSF is not wider than the PSF"),
            std::string::npos)
      << message;
  EXPECT_FALSE(std::filesystem::exists(scratch.path("narrow.fits")));
  app::FitRunOptions ok = options(scratch.path("wide.fits"), 1);
  app::apply_set(ok.config, "metacal=true");
  app::apply_set(ok.config, "metacal_reconvolution_psf=moffat");
  app::apply_set(ok.config, "metacal_psf_dilation=1.2");
  app::FitRun(ok).run();
  io::FitsFile f = io::FitsFile::open_read(scratch.path("wide.fits"));
  f.move_to("RESULTS");
  EXPECT_DOUBLE_EQ(f.read_key_double("metacal_gamma_fwhm").value_or(NAN), 2.85 * 1.2);
}

// metacal cannot deconvolve the Airy disc beyond its cut-off: refused before any fitting.
TEST_F(FitRunTest, MetacalWithAnAiryPsfIsRefusedUpFront) {
  app::FitRunOptions o = options(scratch.path("airy.fits"), 1);
  app::apply_set(o.config, "metacal=true");
  app::apply_set(o.config, "psf_input=airy");
  const std::string message = stampede::testing::error_of<io::ConfigError>([&] { app::FitRun(o).run(); });
  EXPECT_NE(message.find("metacal = true needs psf_input = moffat, moffat_catalog or image"), std::string::npos) << message;
}

TEST_F(FitRunTest, WithoutAnOutputTheRowsOnlyGoToTheCaller) {
  app::FitRunOptions o = options("", 2);
  long long n = 0;
  o.on_rows = [&](std::span<const ObjectRecord> rows) { n += static_cast<long long>(rows.size()); };
  const app::RunSummary s = app::FitRun(o).run();
  EXPECT_EQ(n, kNx * kNy);
  EXPECT_EQ(s.BriefReport().find("wrote"), std::string::npos);
  o.resume = true;
  EXPECT_THROW(app::FitRun(o).run(), std::invalid_argument);
}

TEST_F(FitRunTest, WarningsGoToTheCallback) {
  // The grid records the set's PSF (FWHM 2.85): a run with another FWHM is warned about through
  // on_warning, without the command's prefix, and the run goes on.
  app::FitRunOptions o = options(scratch.path("w.fits"), 1);
  app::apply_set(o.config, "psf_fwhm=3");
  std::vector<std::string> warnings;
  o.on_warning = [&](const std::string& w) { warnings.push_back(w); };
  const app::RunSummary s = app::FitRun(o).run();
  EXPECT_EQ(s.objects, kNx * kNy);
  ASSERT_EQ(warnings.size(), 1u);
  EXPECT_EQ(warnings[0].find(input + "[HDU 0] records a PSF other than the run's: PSFFWHM = 2.85 (psf_fwhm = 3)"), 0u)
      << warnings[0];
}

// Files a run leaves beside its output.
std::vector<std::string> leftovers(const std::string& out) {
  std::vector<std::string> found;
  for (const char* suffix : {"", ".partial", ".checkpoint", ".checkpoint.tmp", ".lock"})
    if (io::file_exists(out + suffix)) found.push_back(out + suffix);
  return found;
}

TEST_F(FitRunTest, AFailedRunRemovesItsPartialOutputs) {
  const std::string out = scratch.path("failed.fits");
  app::FitRunOptions o = options(out, 2);
  o.text_output = scratch.path("failed.txt");
  int batches = 0;
  o.on_rows = [&](std::span<const ObjectRecord>) {
    if (++batches == 2) throw std::runtime_error("the caller gave up");  // after a committed batch
  };
  EXPECT_TRUE(stampede::testing::Contains(stampede::testing::error_of<std::runtime_error>([&] { app::FitRun(o).run(); }),
                                          "the caller gave up"));
  EXPECT_EQ(batches, 2);
  EXPECT_EQ(leftovers(out), std::vector<std::string>{});
  EXPECT_EQ(leftovers(o.text_output), std::vector<std::string>{});
  // Nothing is left to resume, and a fresh run goes through.
  o.on_rows = nullptr;
  EXPECT_EQ(app::FitRun(o).run().objects, kNx * kNy);
  EXPECT_EQ(leftovers(out), std::vector<std::string>{out});
}

TEST_F(FitRunTest, AStoppedRunKeepsItsPartialOutputsForResume) {
  const std::string out = scratch.path("stopped.fits");
  std::atomic<bool> stop{false};
  app::FitRunOptions o = options(out, 1);
  // The reader may run a pool of batches (3 on one thread) ahead of the writer and reads one more
  // while it waits for the first to come back, so the stop is certain to cut the run only when it
  // has more than 4 batches: 6 of 2 here (with 3 of 5 it raced the writer thread).
  app::apply_set(o.config, "batch_size=2");
  o.stop = &stop;
  o.on_rows = [&](std::span<const ObjectRecord>) { stop.store(true); };  // after the first committed batch
  const app::RunSummary s = app::FitRun(o).run();
  EXPECT_TRUE(s.interrupted);
  EXPECT_GT(s.objects, 0);
  EXPECT_LT(s.objects, kNx * kNy);
  EXPECT_TRUE(stampede::testing::Contains(s.BriefReport(), "interrupted: " + out + ".partial kept"));
  EXPECT_EQ(leftovers(out), (std::vector<std::string>{out + ".partial", out + ".checkpoint"}));
  // Resumed, the table equals an uninterrupted run's.
  o.stop = nullptr;
  o.on_rows = nullptr;
  o.resume = true;
  const app::RunSummary rest = app::FitRun(o).run();
  EXPECT_FALSE(rest.interrupted);
  EXPECT_EQ(rest.resumed, s.objects);
  EXPECT_EQ(rest.resumed + rest.objects, kNx * kNy);
  app::FitRunOptions whole = options(scratch.path("whole.fits"), 2);
  app::FitRun(whole).run();
  for (const char* name : {"e1", "e2", "radius", "likelihood", "status"}) {
    const auto a = column(out, name), b = column(whole.output, name);
    ASSERT_EQ(a.size(), b.size());
    for (std::size_t i = 0; i < a.size(); ++i) EXPECT_TRUE(same_bits(a[i], b[i])) << name << " row " << i;
  }
}

TEST_F(FitRunTest, TheOutputIsLockedForTheRunsLife) {
  const std::string out = scratch.path("locked.fits");
  app::FitRunOptions o = options(out, 1);
  std::string second_run, lock_seen;
  o.on_rows = [&](std::span<const ObjectRecord>) {
    if (!second_run.empty()) return;
    lock_seen = io::file_exists(io::OutputLock::path_for(out)) ? "yes" : "no";
    app::FitRunOptions again = options(out, 1);
    again.overwrite = true;  // not a way around the lock
    second_run = stampede::testing::error_of<io::FileError>([&] { app::FitRun(again).run(); });
  };
  app::FitRun(o).run();
  EXPECT_EQ(lock_seen, "yes");
  EXPECT_TRUE(stampede::testing::Contains(second_run, "'" + out + "' is in use by another run: '" + out +
                                                          ".lock' is held by 'pid " + std::to_string(getpid())));
  EXPECT_EQ(leftovers(out), std::vector<std::string>{out});  // the lock is gone with the run
  EXPECT_EQ(column(out, "id").size(), static_cast<std::size_t>(kNx * kNy));
}

TEST_F(FitRunTest, AnExistingOutputIsReplacedOnlyWithOverwrite) {
  const std::string out = scratch.path("again.fits");
  app::FitRun(options(out, 1)).run();
  EXPECT_TRUE(stampede::testing::Contains(
      stampede::testing::error_of<io::FileError>([&] { app::FitRun(options(out, 1)).run(); }),
      "'" + out + "' exists (use --overwrite to replace it)"));
  app::FitRunOptions o = options(out, 1);
  o.overwrite = true;
  EXPECT_EQ(app::FitRun(o).run().objects, kNx * kNy);
  // The input itself is never an output, overwrite or not.
  o.output = input;
  EXPECT_TRUE(stampede::testing::Contains(stampede::testing::error_of<io::FileError>([&] { app::FitRun(o).run(); }),
                                          "-o '" + input + "' is the input '" + input + "'"));
}

}  // namespace
