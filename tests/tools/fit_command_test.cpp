// End-to-end tests of `stampede fit`, running the real binary: the GREAT08-mini sets, identical
// output for any thread count, kill -9 and --resume, memory bounded by the batch, bad input.
#include <fitsio.h>
#include <gtest/gtest.h>
#include <signal.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cmath>
#include <cstring>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <functional>
#include <iterator>
#include <optional>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "io/fits_file.hpp"
#include "support/fit_output.hpp"

namespace fs = std::filesystem;

namespace {

using stampede::testing::column;
using stampede::testing::expect_tables_equal;
using stampede::testing::finish;
using stampede::testing::kGreat08Psf;
using stampede::testing::RunResult;
using stampede::testing::spawn;
using stampede::testing::operator+;
using FitCommand = stampede::testing::FitCommandTest;

std::string data(const std::string& rel) { return std::string(STAMPEDE_DATA_DIR) + "/" + rel; }

// A cheap configuration for the engine-level tests (results need not be accurate, only identical).
const std::vector<std::string> kCheap = {"--set", "upsampling=2", "--set", "n_central_pixels_to_upsample=1", "--set",
                                        "padding=0", "--set", "minimizer_max_iterations=20"};

// Must-show 1: both GREAT08-mini sets give 400 rows; the noise-free mean e matches the truth.
TEST_F(FitCommand, Great08MiniSetsEndToEnd) {
  for (const std::string set : {"nf", "snr40"}) {
    const std::string out = path(set + ".fits");
    std::vector<std::string> args = {data("galsim-great08-mini/" + set + "/set_0.fits"), "-o", out, "--threads", "2"};
    if (set == "snr40") args = args + std::vector<std::string>{"--set", "noise_sigma=1"};
    const RunResult r = run(args + kGreat08Psf);
    ASSERT_EQ(r.exit_code, 0) << r.err;
    EXPECT_NE(r.err.find("400 objects"), std::string::npos) << r.err;
    const auto e1 = column(out, "e1"), e2 = column(out, "e2"), status = column(out, "status"), id = column(out, "id");
    ASSERT_EQ(e1.size(), 400u);
    for (int i = 0; i < 400; ++i) EXPECT_EQ(id[i], i);
    auto truth = stampede::io::FitsFile::open_read(data("galsim-great08-mini/" + set + "/truth_0.fits"));
    truth.move_to("TRUTH");
    const auto t1 = truth.read_column("e1_obs"), t2 = truth.read_column("e2_obs");
    double m1 = 0, m2 = 0, mt1 = 0, mt2 = 0;
    int ok = 0;
    for (int i = 0; i < 400; ++i) {
      ok += status[i] == 0;
      m1 += e1[i] / 400, m2 += e2[i] / 400, mt1 += t1[i] / 400, mt2 += t2[i] / 400;
    }
    std::printf("%s: %d ok, mean e (%+.5f, %+.5f), truth (%+.5f, %+.5f)\n", set.c_str(), ok, m1, m2, mt1, mt2);
    if (set == "nf") {
      EXPECT_EQ(ok, 400);
      EXPECT_LT(std::abs(m1 - mt1), 1e-3);
      EXPECT_LT(std::abs(m2 - mt2), 1e-3);
    } else {
      EXPECT_GE(ok, 390);  // noisy fits may hit the iteration limit; they are flagged rows, never missing
    }
  }
}

// Must-show 2: identical tables (bitwise, all columns but time_us) for --threads 1 and 2.
TEST_F(FitCommand, IdenticalOutputForAnyThreadCount) {
  const std::string in = data("galsim-great08-mini/snr40/set_0.fits");
  const std::vector<std::string> opts = kCheap + kGreat08Psf + std::vector<std::string>{"--set", "noise_sigma=1", "--set", "batch_size=7"};
  ASSERT_EQ(run(std::vector<std::string>{in, "-o", path("t1.fits"), "--threads", "1", "--quiet"} + opts).exit_code, 0);
  ASSERT_EQ(run(std::vector<std::string>{in, "-o", path("t2.fits"), "--threads", "2", "--quiet"} + opts).exit_code, 0);
  expect_tables_equal(path("t1.fits"), path("t2.fits"));
}

// Must-show 3: kill -9 in the middle of a run, then --resume, equals an uninterrupted run.
TEST_F(FitCommand, KillNineThenResumeEqualsUninterruptedRun) {
  const std::string in = data("galsim-great08-mini/snr40/set_0.fits");
  // The upsampled renderer: a run slow enough (~6 s) to be killed mid-way whatever the machine's load.
  const std::vector<std::string> opts = kGreat08Psf + std::vector<std::string>{"--set", "noise_sigma=1", "--set", "batch_size=10",
                                                                               "--set", "renderer=upsampled", "--threads", "2", "--quiet"};
  ASSERT_EQ(run(std::vector<std::string>{in, "-o", path("full.fits")} + opts).exit_code, 0);
  const std::string out = path("resumed.fits");
  const pid_t pid = spawn(std::vector<std::string>{in, "-o", out} + opts, path("stderr.txt"));
  // Wait until some batches are committed, then kill without warning.
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(120);
  while (!fs::exists(out + ".checkpoint") && std::chrono::steady_clock::now() < deadline)
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  std::this_thread::sleep_for(std::chrono::milliseconds(1500));
  ASSERT_EQ(kill(pid, SIGKILL), 0);
  const RunResult killed = finish(pid, path("stderr.txt"));
  ASSERT_EQ(killed.exit_code, 128 + SIGKILL) << "the run finished before it could be killed";
  ASSERT_FALSE(fs::exists(out));
  const RunResult resumed = run(std::vector<std::string>{in, "-o", out, "--resume"} + opts);
  ASSERT_EQ(resumed.exit_code, 0) << resumed.err;
  expect_tables_equal(path("full.fits"), out);
}

// Issue 19, job arrays: a shard killed mid-run resumes only as itself (another shard index is
// refused by the fingerprint) and the shards merged equal the single run.
TEST_F(FitCommand, KilledShardResumesAsItselfAndTheMergeEqualsTheSingleRun) {
  const std::string in = data("galsim-great08-mini/snr40/set_0.fits");
  // The upsampled renderer (~10x the exact fit's time): an exact shard of 200 fits could finish
  // within the 500 ms between its first commit and the kill on a quiet machine.
  const std::vector<std::string> opts = kGreat08Psf + std::vector<std::string>{"--set", "noise_sigma=1", "--set", "renderer=upsampled",
                                                                               "--set", "batch_size=5", "--threads", "2", "--quiet"};
  ASSERT_EQ(run(std::vector<std::string>{in, "-o", path("full.fits")} + opts).exit_code, 0);
  ASSERT_EQ(run(std::vector<std::string>{in, "-o", path("s0.fits"), "--shard", "0/2"} + opts).exit_code, 0);
  const std::string out = path("s1.fits");
  const pid_t pid = spawn(std::vector<std::string>{in, "-o", out, "--shard", "1/2"} + opts, path("stderr.txt"));
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(120);
  while (!fs::exists(out + ".checkpoint") && std::chrono::steady_clock::now() < deadline)
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  std::this_thread::sleep_for(std::chrono::milliseconds(500));
  ASSERT_EQ(kill(pid, SIGKILL), 0);
  ASSERT_EQ(finish(pid, path("stderr.txt")).exit_code, 128 + SIGKILL) << "the shard finished before it could be killed";
  const RunResult wrong = run(std::vector<std::string>{in, "-o", out, "--resume", "--shard", "0/2"} + opts);
  EXPECT_EQ(wrong.exit_code, 1);
  EXPECT_NE(wrong.err.find("shard 1/2 of 400"), std::string::npos) << wrong.err;
  const RunResult resumed = run(std::vector<std::string>{in, "-o", out, "--resume", "--shard", "1/2"} + opts);
  ASSERT_EQ(resumed.exit_code, 0) << resumed.err;
  const RunResult merged = finish(spawn({"-o", path("merged.fits"), out, path("s0.fits"), "--quiet"}, path("merge.txt"), "merge"),
                                  path("merge.txt"));
  ASSERT_EQ(merged.exit_code, 0) << merged.err;
  expect_tables_equal(path("full.fits"), path("merged.fits"));
}

// Issue 31: --input-list --resume skips a complete output only when it is this run's (RUNFP: the
// input's content and the options); an input whose content changed, or other options, is refused.
// A list naming a file as its output directory is a clear error.
TEST_F(FitCommand, AListResumeSkipsOnlyTheSameRunsCompleteOutputs) {
  fs::copy_file(data("galsim-great08-mini/nf/set_0.fits"), path("a.fits"));
  std::ofstream(path("list.txt")) << path("a.fits") << "\n";
  const std::vector<std::string> opts = kGreat08Psf + std::vector<std::string>{"--set", "renderer=exact", "--set",
                                                                               "minimizer_max_iterations=2"};
  const std::vector<std::string> list = {"--input-list", path("list.txt"), "-o", path("out")};
  ASSERT_EQ(run(list + opts + std::vector<std::string>{"--quiet"}).exit_code, 0);
  const RunResult same = run(list + opts + std::vector<std::string>{"--resume"});
  EXPECT_EQ(same.exit_code, 0) << same.err;
  EXPECT_NE(same.err.find("a_fit.fits is complete, skipped"), std::string::npos) << same.err;
  const RunResult options = run(list + opts + std::vector<std::string>{"--resume", "--set", "minimizer_max_iterations=3"});
  EXPECT_EQ(options.exit_code, 1);
  EXPECT_NE(options.err.find("a_fit.fits is complete but was written by another run"), std::string::npos) << options.err;
  // ... naming what differs.
  EXPECT_NE(options.err.find("(minimizer_max_iterations = '2' there, '3' in this run)"), std::string::npos) << options.err;
  fs::remove(path("a.fits"));
  fs::copy_file(data("galsim-great08-mini/nf/set_1.fits"), path("a.fits"));  // new content, same path
  const RunResult content = run(list + opts + std::vector<std::string>{"--resume"});
  EXPECT_EQ(content.exit_code, 1);
  EXPECT_NE(content.err.find("is complete but was written by another run"), std::string::npos) << content.err;
  EXPECT_NE(content.err.find("the inputs or options differ (INSETID = '"), std::string::npos) << content.err;
  std::ofstream(path("file")) << "x";
  const RunResult file = run(std::vector<std::string>{"--input-list", path("list.txt"), "-o", path("file")} + opts);
  EXPECT_EQ(file.exit_code, 1);
  EXPECT_NE(file.err.find("' is a file"), std::string::npos) << file.err;
}

// Issue 31: merge compares the inputs' contents, not their paths as typed: the same file reached by
// two paths merges; another file at the same path is refused (by its content: the digest, or the
// simulation identity the set records).
TEST_F(FitCommand, MergeComparesTheInputsContentNotItsPath) {
  fs::create_directories(path("d"));
  fs::copy_file(data("galsim-great08-mini/nf/set_0.fits"), path("d/in.fits"));
  const std::vector<std::string> opts = kGreat08Psf + std::vector<std::string>{"--set", "renderer=exact", "--set",
                                                                               "minimizer_max_iterations=2", "--quiet"};
  ASSERT_EQ(run(std::vector<std::string>{path("d/in.fits"), "-o", path("s0.fits"), "--shard", "0/2"} + opts).exit_code, 0);
  ASSERT_EQ(run(std::vector<std::string>{path("d/./in.fits"), "-o", path("s1.fits"), "--shard", "1/2"} + opts).exit_code, 0);
  auto merge = [&](const std::string& out) {
    return finish(spawn({"-o", path(out), path("s0.fits"), path("s1.fits"), "--quiet"}, path("merge.txt"), "merge"),
                  path("merge.txt"));
  };
  const RunResult same = merge("m.fits");
  EXPECT_EQ(same.exit_code, 0) << same.err;
  fs::remove(path("d/in.fits"));
  fs::copy_file(data("galsim-great08-mini/nf/set_1.fits"), path("d/in.fits"));
  ASSERT_EQ(run(std::vector<std::string>{path("d/in.fits"), "-o", path("s1.fits"), "--shard", "1/2", "--overwrite"} + opts)
                .exit_code,
            0);
  const RunResult other = merge("n.fits");
  EXPECT_NE(other.exit_code, 0);
  EXPECT_NE(other.err.find("is from another run than"), std::string::npos) << other.err;
  EXPECT_FALSE(fs::exists(path("n.fits")));
}

// Issue 31: a set that records its noise (NOISESIG) is weighted with it when the run sets no
// noise_sigma, as its PSF is taken, and the run says so; an explicit noise_sigma wins.
TEST_F(FitCommand, TakesTheNoiseFromTheHeaderWhenTheRunSetsNone) {
  const std::string set = data("galsim-great08-mini/snr40/set_0.fits");  // NOISESIG = 1
  const std::vector<std::string> opts = {"--set", "renderer=exact", "--set", "minimizer_max_iterations=3"};
  const RunResult taken = run(std::vector<std::string>{set, "-o", path("taken.fits")} + opts);
  ASSERT_EQ(taken.exit_code, 0) << taken.err;
  EXPECT_NE(taken.err.find("noise_sigma = 1 taken from"), std::string::npos) << taken.err;
  const RunResult given = run(std::vector<std::string>{set, "-o", path("given.fits"), "--set", "noise_sigma=1"} + opts);
  ASSERT_EQ(given.exit_code, 0) << given.err;
  EXPECT_EQ(given.err.find("taken from"), std::string::npos) << given.err;
  expect_tables_equal(path("taken.fits"), path("given.fits"));
  for (double flags : column(path("taken.fits"), "flags")) EXPECT_EQ(static_cast<long long>(flags) & 64, 0);
  for (double snr : column(path("taken.fits"), "snr")) EXPECT_TRUE(std::isfinite(snr));
}

TEST_F(FitCommand, AnInputListFitsEveryGridToItsOwnTable) {
  const std::string nf0 = data("galsim-great08-mini/nf/set_0.fits"), nf1 = data("galsim-great08-mini/nf/set_1.fits");
  std::ofstream(path("list.txt")) << nf0 << "\n# a comment\n" << nf1 << "\n";
  const std::vector<std::string> opts = kGreat08Psf + std::vector<std::string>{"--set", "renderer=exact", "--set",
                                                                               "minimizer_max_iterations=5", "--quiet"};
  ASSERT_EQ(run(std::vector<std::string>{"--input-list", path("list.txt"), "-o", path("out")} + opts).exit_code, 0);
  ASSERT_EQ(run(std::vector<std::string>{nf1, "-o", path("one.fits")} + opts).exit_code, 0);
  expect_tables_equal(path("one.fits"), path("out/set_1_fit.fits"));
  EXPECT_TRUE(fs::exists(path("out/set_0_fit.fits")));
  const RunResult both = run(std::vector<std::string>{nf0, "--input-list", path("list.txt"), "-o", path("out")});
  EXPECT_EQ(both.exit_code, 1);
  EXPECT_NE(both.err.find("give one"), std::string::npos) << both.err;
  const RunResult again = run(std::vector<std::string>{"--input-list", path("list.txt"), "-o", path("out")} + opts);
  EXPECT_EQ(again.exit_code, 1);  // outputs exist: refused without --resume or --overwrite
  EXPECT_NE(again.err.find("exists"), std::string::npos) << again.err;
}

TEST_F(FitCommand, ShardArgumentErrors) {
  for (const char* bad : {"2/2", "1", "-1/2", "1/0", "a/b", "1/2x"}) {
    const RunResult r = run({data("galsim-great08-mini/nf/set_0.fits"), "-o", path("x.fits"), "--shard", bad});
    EXPECT_EQ(r.exit_code, 1) << bad;
    EXPECT_NE(r.err.find("must be I/N with 0 <= I < N"), std::string::npos) << r.err;
  }
}

// Issue 4, must-show 5: `stampede fit` then `stampede metrics` on both noise-free sets recovers
// each set's shear to 1e-3.
TEST_F(FitCommand, MetricsRecoverTheGreat08MiniShears) {
  std::vector<std::string> metrics_args;
  for (int set : {0, 1}) {
    const std::string out = path("nf" + std::to_string(set) + ".fits");
    const RunResult r = run(std::vector<std::string>{data("galsim-great08-mini/nf/set_" + std::to_string(set) + ".fits"),
                                                     "-o", out, "--quiet"} + kGreat08Psf);
    ASSERT_EQ(r.exit_code, 0) << r.err;
    metrics_args = metrics_args + std::vector<std::string>{"--fit", out, "--truth",
                                                           data("galsim-great08-mini/nf/truth_" + std::to_string(set) + ".fits")};
  }
  metrics_args = metrics_args + std::vector<std::string>{"--json", path("m.json")};
  const RunResult m = finish(spawn(metrics_args, path("stderr.txt"), "metrics", path("report.txt")), path("stderr.txt"));
  ASSERT_EQ(m.exit_code, 0) << m.err;
  std::ifstream report(path("report.txt"));
  std::string line;
  int sets = 0;
  while (std::getline(report, line)) {
    std::istringstream in(line);
    int set;
    double g1t, g1, d1, e1, g2t, g2;
    if (!(in >> set >> g1t >> g1 >> d1 >> e1 >> g2t >> g2)) continue;
    std::printf("set %d: g1 %+.6f (true %+.6f), g2 %+.6f (true %+.6f)\n", set, g1, g1t, g2, g2t);
    EXPECT_LT(std::abs(g1 - g1t), 1e-3) << line;
    EXPECT_LT(std::abs(g2 - g2t), 1e-3) << line;
    ++sets;
  }
  EXPECT_EQ(sets, 2);
  EXPECT_TRUE(fs::exists(path("m.json")));
}

// Writes an nx x ny grid of s x s stamps, each a round Gaussian blob (cheap to make and fit).
// keys: more header keywords for the image HDU.
void write_grid(const std::string& file, int nx, int ny, int s,
                const std::function<void(stampede::io::FitsFile&)>& keys = {}) {
  std::vector<double> img(static_cast<std::size_t>(nx) * s * ny * s);
  for (int iy = 0; iy < ny * s; ++iy)
    for (int ix = 0; ix < nx * s; ++ix) {
      const double dx = ix % s - (s - 1) / 2.0 - 0.1, dy = iy % s - (s - 1) / 2.0 + 0.2;
      img[static_cast<std::size_t>(iy) * nx * s + ix] = 100.0 * std::exp(-(dx * dx + 0.8 * dy * dy) / 4.0);
    }
  auto f = stampede::io::FitsFile::create(file, true);
  f.write_image(static_cast<long>(nx) * s, static_cast<long>(ny) * s, img);
  f.write_key("STAMPSZ", s, "stamp size");
  if (keys) keys(f);
}

// Must-show 4: peak RSS over 40,000 stamps within 20 MB of the run over 4,000. Cheap configuration:
// 9 px stamps, upsampling 1, no central integration, no padding, at most 3 iterations.
TEST_F(FitCommand, MemoryIsBoundedByTheBatchNotTheCatalogue) {
  write_grid(path("small.fits"), 200, 20, 9);
  write_grid(path("large.fits"), 200, 200, 9);
  const std::vector<std::string> cheap = {"--set", "renderer=upsampled", "--set", "upsampling=1", "--set",
                                         "n_central_pixels_to_upsample=0", "--set",
                                         "padding=0", "--set", "minimizer_max_iterations=3", "--threads", "2", "--quiet"};
  const RunResult small = run(std::vector<std::string>{path("small.fits"), "-o", path("small_out.fits")} + cheap);
  const RunResult large = run(std::vector<std::string>{path("large.fits"), "-o", path("large_out.fits")} + cheap);
  ASSERT_EQ(small.exit_code, 0) << small.err;
  ASSERT_EQ(large.exit_code, 0) << large.err;
  EXPECT_EQ(column(path("large_out.fits"), "id").size(), 40000u);
  std::printf("peak RSS: 4,000 stamps %ld kB, 40,000 stamps %ld kB\n", small.max_rss_kb, large.max_rss_kb);
  EXPECT_LT(large.max_rss_kb - small.max_rss_kb, 20 * 1024);
}

// A set that records its PSF (as `stampede sim` and GalSim write them) fitted with another one: a
// warning naming the file and each differing key with both values; none when they agree or when
// the file records no PSF; an incomplete record is a warning too. The fit goes on with the run's PSF.
TEST_F(FitCommand, WarnsWhenTheSetRecordsAnotherPsf) {
  const std::vector<std::string> cheap = {"--set", "renderer=upsampled", "--set", "upsampling=1", "--set",
                                         "n_central_pixels_to_upsample=0", "--set",
                                         "padding=0", "--set", "minimizer_max_iterations=3", "--quiet"};
  write_grid(path("plain.fits"), 2, 2, 9);
  write_grid(path("moffat.fits"), 2, 2, 9, [](stampede::io::FitsFile& f) {
    f.write_key("PSFTYPE", std::string("moffat"), "");
    f.write_key("PSFBETA", 3.0, "");
    f.write_key("PSFFWHM", 2.85, "");
    f.write_key("PSFE1", 0.0, "");
    f.write_key("PSFE2", 0.05, "");
  });
  write_grid(path("airy.fits"), 2, 2, 9, [](stampede::io::FitsFile& f) {
    f.write_key("PSFTYPE", std::string("airy"), "");
    f.write_key("PSFLOD", 2.0, "");
  });
  write_grid(path("partial.fits"), 2, 2, 9, [](stampede::io::FitsFile& f) { f.write_key("PSFBETA", 3.0, ""); });
  // The run sets a PSF option (the header's value): the header's PSF is checked, not used.
  const RunResult differs =
      run(std::vector<std::string>{path("moffat.fits"), "-o", path("a.fits"), "--set", "psf_beta=3"} + cheap);
  ASSERT_EQ(differs.exit_code, 0) << differs.err;
  EXPECT_NE(differs.err.find("warning: " + path("moffat.fits") + "[HDU 0] records a PSF other than the run's"),
            std::string::npos)
      << differs.err;
  EXPECT_NE(differs.err.find("PSFE2 = 0.05 (psf_e2 = 0)"), std::string::npos) << differs.err;
  EXPECT_EQ(differs.err.find("PSFBETA"), std::string::npos) << "only differing keys are named: " << differs.err;
  EXPECT_EQ(column(path("a.fits"), "id").size(), 4u);

  const RunResult agrees = run(std::vector<std::string>{path("moffat.fits"), "-o", path("b.fits"), "--set", "psf_e2=0.05"} + cheap);
  ASSERT_EQ(agrees.exit_code, 0) << agrees.err;
  EXPECT_EQ(agrees.err.find("warning"), std::string::npos) << agrees.err;

  const RunResult plain = run(std::vector<std::string>{path("plain.fits"), "-o", path("c.fits")} + cheap);
  ASSERT_EQ(plain.exit_code, 0) << plain.err;
  EXPECT_EQ(plain.err.find("warning"), std::string::npos) << plain.err;

  const RunResult type =
      run(std::vector<std::string>{path("airy.fits"), "-o", path("d.fits"), "--set", "psf_input=moffat"} + cheap);
  ASSERT_EQ(type.exit_code, 0) << type.err;
  EXPECT_NE(type.err.find("PSFTYPE = 'airy' (psf_input = moffat)"), std::string::npos) << type.err;

  // An incomplete record is not the fit's business: a warning naming the file and key, every row.
  const RunResult partial = run(std::vector<std::string>{path("partial.fits"), "-o", path("e.fits")} + cheap);
  ASSERT_EQ(partial.exit_code, 0) << partial.err;
  EXPECT_NE(partial.err.find("PSF record is unreadable"), std::string::npos) << partial.err;
  EXPECT_NE(partial.err.find("partial.fits"), std::string::npos) << partial.err;
  EXPECT_NE(partial.err.find("PSFFWHM"), std::string::npos) << partial.err;
  EXPECT_EQ(column(path("e.fits"), "id").size(), 4u);
}

// A run that sets no PSF option fits a set that records its PSF with that PSF (what the GREAT08
// sets' users expect), and records it as the effective options; a record the fit cannot use is an
// error naming the file, and one the run overrides is only checked (above).
TEST_F(FitCommand, TakesThePsfFromTheHeaderWhenTheRunSetsNone) {
  const std::vector<std::string> cheap = {"--set", "renderer=upsampled", "--set", "upsampling=1", "--set",
                                         "n_central_pixels_to_upsample=0", "--set",
                                         "padding=0", "--set", "minimizer_max_iterations=3", "--quiet"};
  write_grid(path("moffat.fits"), 2, 2, 9, [](stampede::io::FitsFile& f) {
    f.write_key("PSFBETA", 3.5, "");
    f.write_key("PSFFWHM", 2.5, "");
    f.write_key("PSFE1", -0.02, "");
    f.write_key("PSFE2", 0.05, "");
  });
  write_grid(path("airy.fits"), 2, 2, 9, [](stampede::io::FitsFile& f) {
    f.write_key("PSFTYPE", std::string("airy"), "");
    f.write_key("PSFLOD", 2.0, "");
  });
  write_grid(path("bad.fits"), 2, 2, 9, [](stampede::io::FitsFile& f) {
    f.write_key("PSFBETA", 0.5, "");
    f.write_key("PSFFWHM", 2.5, "");
    f.write_key("PSFE1", 0.0, "");
    f.write_key("PSFE2", 0.0, "");
  });
  const RunResult moffat = run(std::vector<std::string>{path("moffat.fits"), "-o", path("m.fits")} + cheap);
  ASSERT_EQ(moffat.exit_code, 0) << moffat.err;
  EXPECT_EQ(moffat.err.find("warning"), std::string::npos) << moffat.err;
  EXPECT_EQ(column(path("m.fits"), "psf_e1"), std::vector<double>(4, -0.02));
  EXPECT_EQ(column(path("m.fits"), "psf_e2"), std::vector<double>(4, 0.05));
  auto header = stampede::io::FitsFile::open_read(path("m.fits"));
  header.move_to("RESULTS");
  EXPECT_EQ(header.key_double("PSF_BETA"), 3.5);
  EXPECT_EQ(header.key_double("PSF_FWHM"), 2.5);

  const RunResult airy = run(std::vector<std::string>{path("airy.fits"), "-o", path("a.fits")} + cheap);
  ASSERT_EQ(airy.exit_code, 0) << airy.err;
  auto airy_header = stampede::io::FitsFile::open_read(path("a.fits"));
  airy_header.move_to("RESULTS");
  EXPECT_EQ(airy_header.read_key_string("PSF_INPUT"), std::optional<std::string>("airy"));
  EXPECT_EQ(airy_header.key_double("AIRY_LAMBDA_OVER_D"), 2.0);

  const RunResult bad = run(std::vector<std::string>{path("bad.fits"), "-o", path("b.fits")} + cheap);
  EXPECT_NE(bad.exit_code, 0);
  EXPECT_NE(bad.err.find(path("bad.fits") + "[HDU 0] records a PSF the fit cannot use (psf_beta = 0.5"),
            std::string::npos)
      << bad.err;
  // With the PSF set, the same file fits (and is warned about).
  const RunResult set = run(std::vector<std::string>{path("bad.fits"), "-o", path("b.fits"), "--set", "psf_beta=3"} + cheap);
  ASSERT_EQ(set.exit_code, 0) << set.err;
  EXPECT_NE(set.err.find("PSFBETA = 0.5 (psf_beta = 3)"), std::string::npos) << set.err;
}

// The type CFITSIO reads a RESULTS header key's card as: 'C' string, 'I' integer, 'F' real.
char results_card_type(const std::string& file, const std::string& key) {
  fitsfile* f = nullptr;
  char value[FLEN_VALUE] = {}, comment[FLEN_COMMENT] = {};
  char type = '?';
  int status = 0;
  fits_open_file(&f, (file + "[RESULTS]").c_str(), READONLY, &status);
  fits_read_keyword(f, key.c_str(), value, comment, &status);
  fits_get_keytype(value, &type, &status);
  int close_status = 0;
  if (f) fits_close_file(f, &close_status);
  return status == 0 ? type : '?';
}

// The effective options in the output header keep their types: integers and reals as number
// cards, text (and 'auto' starts) as strings.
TEST_F(FitCommand, HeaderNumbersAreNumberCards) {
  write_grid(path("g.fits"), 1, 1, 9);
  const RunResult r = run({path("g.fits"), "-o", path("o.fits"), "--set", "noise_sigma=0.5", "--set",
                           "minimizer_max_iterations=3", "--quiet"});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_EQ(results_card_type(path("o.fits"), "STAMP_SIZE"), 'I');
  EXPECT_EQ(results_card_type(path("o.fits"), "PADDING"), 'I');
  EXPECT_EQ(results_card_type(path("o.fits"), "MINIMIZER_MAX_ITERATIONS"), 'I');
  EXPECT_EQ(results_card_type(path("o.fits"), "NOISE_SIGMA"), 'F');
  EXPECT_EQ(results_card_type(path("o.fits"), "PSF_BETA"), 'F');
  EXPECT_EQ(results_card_type(path("o.fits"), "LEVMAR_EPS4"), 'F');
  EXPECT_EQ(results_card_type(path("o.fits"), "PSF_INPUT"), 'C');
  EXPECT_EQ(results_card_type(path("o.fits"), "INPUT"), 'C');
  auto f = stampede::io::FitsFile::open_read(path("o.fits"));
  f.move_to("RESULTS");
  EXPECT_EQ(f.key_long("STAMP_SIZE"), 9);
  EXPECT_EQ(f.key_double("NOISE_SIGMA"), 0.5);
  EXPECT_EQ(f.key_double("LEVMAR_EPS4"), 1e-6);
}

TEST_F(FitCommand, BadInputGivesAClearErrorBeforeFitting) {
  struct Case {
    std::vector<std::string> args;
    std::string expect;
  };
  std::ofstream(path("bad.fits")) << "this is not FITS";
  std::ofstream(path("cat.txt")) << "# id x\n1 10.5\n";
  const std::string grid = data("galsim-great08-mini/nf/set_0.fits");
  const Case cases[] = {
      {{path("missing.fits"), "-o", path("o.fits")}, "missing.fits"},
      {{path("bad.fits"), "-o", path("o.fits")}, "bad.fits"},
      {{grid, "-o", path("o.fits"), "--set", "stamp_size=40"}, "does not divide"},
      {{grid, "-o", path("o.fits"), "--catalog", path("cat.txt"), "--set", "stamp_size=39"}, "cat.txt:2"},
      {{grid, "-o", path("o.fits"), "--set", "upsampling=-1"}, "upsampling"},
      {{grid, "-o", path("o.fits"), "--set", "nonsense=1"}, "nonsense"},
      {{grid, "-o", path("o.fits"), "--set", "psf_input=image", "--set", "psf_image=" + path("missing_psf.fits")}, "missing_psf.fits"},
      {{grid, "-o", "/nonexistent/dir/o.fits"}, "/nonexistent/dir/o.fits"},
      {{grid, "-o", path("o.fits"), "--weight", data("galsim-great08-mini/nf/psf_0.fits")}, "weight"},
  };
  for (const Case& c : cases) {
    const RunResult r = run(c.args);
    EXPECT_NE(r.exit_code, 0) << c.expect;
    EXPECT_NE(r.err.find(c.expect), std::string::npos) << "stderr '" << r.err << "' lacks '" << c.expect << "'";
    // Rejected before any fitting: no output was started (no table, partial or checkpoint).
    for (const char* suffix : {"", ".partial", ".checkpoint"})
      EXPECT_FALSE(fs::exists(path("o.fits") + suffix)) << c.expect << ": " << suffix;
  }
}

// Issue 17 items 1 and 3: while a run writes an output, a second run on it is refused naming the
// first's pid; after a kill -9 (the lock file left behind, its flock gone) --resume is not blocked,
// but is refused, naming the file, when the input's content was replaced at the same path (same
// size, one byte changed); with the original content back it completes to the uninterrupted table.
TEST_F(FitCommand, LockedWhileRunningAndResumeChecksTheInputsContent) {
  const std::string in = path("in.fits");
  stampede::testing::write_great08_stamps(in, 10, 4);
  const std::vector<std::string> opts = kGreat08Psf + std::vector<std::string>{"--set", "batch_size=2", "--threads", "1", "--quiet"};
  ASSERT_EQ(run(std::vector<std::string>{in, "-o", path("full.fits")} + opts).exit_code, 0);
  const std::string out = path("resumed.fits");
  const pid_t pid = spawn(std::vector<std::string>{in, "-o", out} + opts, path("first.txt"));
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(120);
  while (!fs::exists(out + ".checkpoint") && std::chrono::steady_clock::now() < deadline)
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  const RunResult second = run(std::vector<std::string>{in, "-o", out, "--overwrite"} + opts);
  EXPECT_NE(second.exit_code, 0);
  EXPECT_NE(second.err.find("'" + out + "' is in use by another run: '" + out + ".lock' is held by 'pid " +
                            std::to_string(pid) + " on host "),
            std::string::npos)
      << second.err;
  ASSERT_EQ(kill(pid, SIGKILL), 0);
  ASSERT_EQ(finish(pid, path("first.txt")).exit_code, 128 + SIGKILL) << "the run finished before it could be killed";
  ASSERT_TRUE(fs::exists(out + ".lock"));  // left by the killed run, no longer locked
  ASSERT_TRUE(fs::exists(out + ".partial"));

  // The same size, one data byte changed at the same path.
  std::string bytes;
  {
    std::ifstream f(in, std::ios::binary);
    bytes.assign(std::istreambuf_iterator<char>(f), std::istreambuf_iterator<char>());
  }
  std::string changed = bytes;
  changed[changed.size() - 3000] ^= 0x10;
  std::ofstream(in, std::ios::binary | std::ios::trunc) << changed;
  const RunResult refused = run(std::vector<std::string>{in, "-o", out, "--resume"} + opts);
  EXPECT_NE(refused.exit_code, 0);
  EXPECT_NE(refused.err.find("was written by a different run (input or configuration changed): it records 'input " + in +
                             ": " + std::to_string(bytes.size()) + " bytes, xxh64 "),
            std::string::npos)
      << refused.err;
  ASSERT_TRUE(fs::exists(out + ".partial")) << "a refused resume keeps the run resumable";

  std::ofstream(in, std::ios::binary | std::ios::trunc) << bytes;
  const RunResult resumed = run(std::vector<std::string>{in, "-o", out, "--resume"} + opts);
  ASSERT_EQ(resumed.exit_code, 0) << resumed.err;
  expect_tables_equal(path("full.fits"), out);
  for (const char* suffix : {".partial", ".checkpoint", ".lock"}) EXPECT_FALSE(fs::exists(out + suffix)) << suffix;
}

// Issue 17 item 2 and the up-front rejections: an output that is the input (by any name, or whose
// partial is), a directory, or an existing file without --overwrite is refused before any fitting,
// leaving the files as they were; --overwrite replaces an existing table.
TEST_F(FitCommand, OutputsAreCheckedBeforeFitting) {
  const std::vector<std::string> cheap = {"--set", "renderer=upsampled", "--set", "upsampling=1", "--set",
                                         "n_central_pixels_to_upsample=0", "--set",
                                         "padding=0", "--set", "minimizer_max_iterations=3", "--quiet"};
  write_grid(path("in.fits"), 2, 2, 9);
  fs::create_symlink(path("in.fits"), path("alias.fits"));
  fs::copy_file(path("in.fits"), path("t.fits.partial"));
  fs::create_directory(path("outdir"));
  std::ofstream(path("old.fits")) << "an earlier table";
  const auto size = fs::file_size(path("in.fits"));
  struct Case {
    std::vector<std::string> args;
    std::string expect;
  };
  const Case cases[] = {
      {{path("in.fits"), "-o", path("in.fits"), "--overwrite"}, "is the input '" + path("in.fits") + "'"},
      {{path("in.fits") + "[0]", "-o", path("alias.fits"), "--overwrite"}, "is the input '" + path("in.fits") + "'"},
      {{path("in.fits"), "-o", path("o.fits"), "--text", path("in.fits"), "--overwrite"}, "--text '" + path("in.fits") + "' is the input"},
      {{path("t.fits.partial"), "-o", path("t.fits")}, "the run writes '" + path("t.fits.partial") + "', which is the input"},
      {{path("in.fits"), "-o", path("outdir")}, "-o '" + path("outdir") + "' is a directory"},
      {{path("in.fits"), "-o", path("old.fits")}, "'" + path("old.fits") + "' exists (use --overwrite to replace it)"},
  };
  for (const Case& c : cases) {
    const RunResult r = run(c.args + cheap);
    EXPECT_NE(r.exit_code, 0) << c.expect;
    EXPECT_NE(r.err.find(c.expect), std::string::npos) << "stderr '" << r.err << "' lacks '" << c.expect << "'";
  }
  EXPECT_EQ(fs::file_size(path("in.fits")), size);
  EXPECT_EQ(fs::file_size(path("t.fits.partial")), size);
  EXPECT_EQ(fs::file_size(path("old.fits")), std::string("an earlier table").size());
  for (const char* left : {"outdir.partial", "outdir.checkpoint", "o.fits", "o.fits.partial", "t.fits", "old.fits.partial"})
    EXPECT_FALSE(fs::exists(path(left))) << left;
  const RunResult replaced = run(std::vector<std::string>{path("in.fits"), "-o", path("old.fits"), "--overwrite"} + cheap);
  ASSERT_EQ(replaced.exit_code, 0) << replaced.err;
  EXPECT_EQ(column(path("old.fits"), "id").size(), 4u);
}

// A bad value is echoed at most ~80 bytes of it, escaped: a 100 kB --set value, a 5 MB ini value.
TEST_F(FitCommand, ErrorsQuoteABadValueShortAndEscaped) {
  const std::string grid = data("galsim-great08-mini/nf/set_0.fits");
  const RunResult set = run({grid, "-o", path("o.fits"), "--set", "psf_fwhm=" + std::string(100000, '7') + "\x01"});
  EXPECT_NE(set.exit_code, 0);
  EXPECT_NE(set.err.find("option 'psf_fwhm' = '7777"), std::string::npos) << set.err;
  EXPECT_NE(set.err.find("77\\x01' (100001 bytes): "), std::string::npos) << set.err;
  EXPECT_LT(set.err.size(), 400u) << set.err;
  std::ofstream(path("run.ini")) << "psf_fwhm = " << std::string(5'000'000, '\x1b') << "\n";
  const RunResult ini = run({grid, "-o", path("o.fits"), "--config", path("run.ini")});
  EXPECT_NE(ini.exit_code, 0);
  EXPECT_NE(ini.err.find(path("run.ini") + ":1: option 'psf_fwhm' = '\\x1b\\x1b"), std::string::npos) << ini.err.substr(0, 500);
  EXPECT_NE(ini.err.find("' (5000000 bytes): expected a number"), std::string::npos) << ini.err.substr(0, 500);
  EXPECT_LT(ini.err.size(), 600u);
  EXPECT_EQ(ini.err.find('\x1b'), std::string::npos) << "no raw escape byte reaches the terminal";
}

// A run that hits the file-size limit (`ulimit -f`) says so, exits non-zero and keeps its committed
// rows: --resume after raising the limit gives the table of an uninterrupted run. (Before: "cannot
// flush ...: CFITSIO status 106", and the partial and checkpoint were deleted.)
TEST_F(FitCommand, AFileSizeLimitKeepsTheCommittedRowsForResume) {
  const std::string in = data("galsim-great08-mini/nf/set_0.fits");
  const std::vector<std::string> opts =
      kCheap + kGreat08Psf + std::vector<std::string>{"--set", "batch_size=20", "--threads", "2", "--quiet"};
  ASSERT_EQ(run(std::vector<std::string>{in, "-o", path("full.fits")} + opts).exit_code, 0);
  const std::string out = path("limited.fits");
  // About a third of the table's rows fit under 60000 bytes (a row is ~210 bytes, the header ~20 KB).
  const RunResult limited = finish(spawn(std::vector<std::string>{in, "-o", out} + opts, path("limited_err.txt"), "fit",
                                         "/dev/null", 60000),
                                   path("limited_err.txt"));
  EXPECT_EQ(limited.exit_code, 1) << limited.err;
  EXPECT_NE(limited.err.find("the file-size limit of this process (RLIMIT_FSIZE, `ulimit -f`) of 60000 bytes is reached"),
            std::string::npos) << limited.err;
  EXPECT_NE(limited.err.find("rows committed before it are kept in '" + out + ".partial'"), std::string::npos)
      << limited.err;
  ASSERT_TRUE(fs::exists(out + ".partial") && fs::exists(out + ".checkpoint")) << limited.err;
  ASSERT_FALSE(fs::exists(out));
  const RunResult resumed = run(std::vector<std::string>{in, "-o", out, "--resume"} + opts);
  ASSERT_EQ(resumed.exit_code, 0) << resumed.err;
  expect_tables_equal(path("full.fits"), out);
}

// A file-size limit of any size up to the table's, met anywhere (a commit, the final close, whose
// blocks CFITSIO writes and can lose without a word), never leaves a short table reported complete;
// --resume then gives the uninterrupted table, or starts the run where nothing was committed.
// (Before: limits within ~4.5 KiB of the end gave exit 0 and a short table; a limit that cut a
// buffered write was committed as if written, and resume found the partial "corrupt".)
TEST_F(FitCommand, EveryFileSizeLimitResumesToTheUninterruptedTable) {
  const std::string in = data("galsim-great08-mini/nf/set_0.fits");
  const std::vector<std::string> opts =
      kCheap + kGreat08Psf + std::vector<std::string>{"--set", "batch_size=20", "--threads", "2", "--quiet"};
  ASSERT_EQ(run(std::vector<std::string>{in, "-o", path("full.fits")} + opts).exit_code, 0);
  const long long size = static_cast<long long>(fs::file_size(path("full.fits")));
  std::vector<long long> limits;
  for (long long limit = 8192; limit < size - 8192; limit += 12288) limits.push_back(limit);
  for (long long back : {8192LL, 4096LL, 2048LL, 512LL, 1LL, 0LL}) limits.push_back(size - back);
  int resumed = 0, started = 0, whole = 0;
  for (const long long limit : limits) {
    std::string name = std::to_string(limit);
    name.append(".fits");
    const std::string out = path(name);
    const RunResult r = finish(spawn(std::vector<std::string>{in, "-o", out} + opts, out + ".err", "fit", "/dev/null", limit),
                               out + ".err");
    if (r.exit_code == 0) {
      EXPECT_EQ(static_cast<long long>(fs::file_size(out)), size) << "limit " << limit << ": " << r.err;
      expect_tables_equal(path("full.fits"), out);
      ++whole;
      continue;
    }
    EXPECT_EQ(r.exit_code, 1) << r.err;
    EXPECT_FALSE(fs::exists(out)) << "limit " << limit;
    EXPECT_NE(r.err.find("file-size limit"), std::string::npos) << r.err;
    const bool kept = fs::exists(out + ".checkpoint");
    const RunResult again = run(std::vector<std::string>{in, "-o", out, "--resume"} + opts);
    ASSERT_EQ(again.exit_code, 0) << "limit " << limit << ": " << again.err;
    expect_tables_equal(path("full.fits"), out);
    ++(kept ? resumed : started);
  }
  std::printf("%zu limits: %d resumed, %d started by --resume, %d whole\n", limits.size(), resumed, started, whole);
  EXPECT_GT(resumed, 3);
  EXPECT_GT(started, 0);
  EXPECT_GT(whole, 0);
}

// --resume of an output the run already finished: says it is complete, exits 0 and leaves it
// untouched (it used to fail with "'OUT.checkpoint' does not exist"); another run's complete output
// is refused.
TEST_F(FitCommand, ResumingACompleteOutputLeavesItAsItIs) {
  const std::string in = data("galsim-great08-mini/nf/set_0.fits");
  const std::vector<std::string> opts = kCheap + kGreat08Psf + std::vector<std::string>{"--threads", "2"};
  const std::string out = path("done.fits");
  ASSERT_EQ(run(std::vector<std::string>{in, "-o", out, "--quiet"} + opts).exit_code, 0);
  const auto before = fs::last_write_time(out);
  std::ifstream a(out, std::ios::binary);
  const std::string bytes((std::istreambuf_iterator<char>(a)), std::istreambuf_iterator<char>());
  const RunResult again = run(std::vector<std::string>{in, "-o", out, "--resume"} + opts);
  EXPECT_EQ(again.exit_code, 0) << again.err;
  EXPECT_NE(again.err.find(out + " is complete, skipped"), std::string::npos) << again.err;
  EXPECT_EQ(fs::last_write_time(out), before);
  std::ifstream b(out, std::ios::binary);
  EXPECT_TRUE(std::string((std::istreambuf_iterator<char>(b)), std::istreambuf_iterator<char>()) == bytes);
  EXPECT_FALSE(fs::exists(out + ".partial") || fs::exists(out + ".checkpoint"));
  const RunResult other = run(std::vector<std::string>{in, "-o", out, "--resume"} + opts +
                              std::vector<std::string>{"--set", "minimizer_max_iterations=3"});
  EXPECT_EQ(other.exit_code, 1);
  EXPECT_NE(other.err.find("is complete but was written by another run"), std::string::npos) << other.err;
}

// Band names that differ only in case: FITS column lookup ignores case, so flux_G and flux_g were one
// column to readers and merge (both read G's values). Refused before any work, naming the option
// and both names; `sim meds`, whose tiles' directories the names are, likewise.
TEST_F(FitCommand, BandNamesDifferingOnlyInCaseAreRefused) {
  const RunResult r = run({"--meds", path("g.fits"), "--meds", path("r.fits"), "--bands", "G,g", "-o", path("o.fits")});
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_NE(r.err.find("--bands: bands 'G' and 'g' differ only in case"), std::string::npos) << r.err;
  const RunResult sim =
      finish(spawn({"meds", "--out", path("sim"), "--bands", "r,g,R", "--objects", "2"}, path("sim.txt"), "sim"), path("sim.txt"));
  EXPECT_EQ(sim.exit_code, 1);
  EXPECT_NE(sim.err.find("--bands 'r,g,R': bands 'r' and 'R' differ only in case"), std::string::npos) << sim.err;
  EXPECT_FALSE(fs::exists(path("o.fits")));
  EXPECT_FALSE(fs::exists(path("sim")));
}

// --bands (or another one-value option) given twice: the last used to win silently; refused before
// any work.
TEST_F(FitCommand, OptionsGivenTwiceAreRefused) {
  const RunResult r = run({"--meds", path("g.fits"), "--meds", path("r.fits"), "--bands", "g,r", "--bands", "r,g", "-o",
                           path("o.fits")});
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_NE(r.err.find("--bands 'r,g': --bands is given twice (first 'g,r')"), std::string::npos) << r.err;
  const std::string grid = data("galsim-great08-mini/nf/set_0.fits");
  const RunResult o = run({grid, "-o", path("a.fits"), "--output", path("b.fits")});
  EXPECT_EQ(o.exit_code, 1);
  EXPECT_NE(o.err.find("-o is given twice"), std::string::npos) << o.err;
  const RunResult t = run({grid, "-o", path("a.fits"), "--threads", "1", "--threads", "2"});
  EXPECT_EQ(t.exit_code, 1);
  EXPECT_NE(t.err.find("--threads is given twice"), std::string::npos) << t.err;
  for (const char* name : {"a.fits", "b.fits", "a.fits.partial", "o.fits"}) EXPECT_FALSE(fs::exists(path(name))) << name;
  // The same class in `sim meds`, whose --bands also name the tiles: the last used to win.
  const RunResult sim = finish(spawn({"meds", "--out", path("sim"), "--bands", "g,r", "--objects", "2", "--bands", "i"},
                                     path("sim.txt"), "sim"),
                               path("sim.txt"));
  EXPECT_EQ(sim.exit_code, 1);
  EXPECT_NE(sim.err.find("--bands is given twice: give it once (see stampede sim meds --help)"), std::string::npos)
      << sim.err;
  EXPECT_FALSE(fs::exists(path("sim")));
}

}  // namespace
