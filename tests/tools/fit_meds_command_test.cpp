// `stampede fit --meds` end to end, running the real binary on the `meds` package's sample tile:
// one row per object in object_data order with the survey columns, the same table for any thread
// count, kill -9 and --resume, and bad input (issue 20, must-show 6) as a clear error naming the
// file, HDU and column, or as flagged rows whose warnings name the object and column.
#include <gtest/gtest.h>
#include <signal.h>

#include <chrono>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>
#include <thread>
#include <vector>

#include "engine/pipeline/object_record.hpp"
#include "io/fits_file.hpp"
#include "support/fit_output.hpp"
#include "support/meds_edit.hpp"

namespace fs = std::filesystem;

namespace {

using stampede::testing::column;
using stampede::testing::expect_tables_equal;
using stampede::testing::finish;
using stampede::testing::RunResult;
using stampede::testing::spawn;
using stampede::testing::operator+;
using FitMeds = stampede::testing::FitCommandTest;

const std::string kSample = std::string(STAMPEDE_DATA_DIR) + "/meds-sample";
const std::vector<std::string> kSurveyColumns = {
    "id", "number", "ra", "dec", "x0", "y0", "e1", "e2", "radius", "bulge_A", "disc_A", "bulge_flux", "disc_flux",
    "flux", "e1_err", "e2_err", "snr", "chi2", "likelihood", "n_iter", "n_eval", "stop_reason", "status", "flags",
    "psf_e1", "psf_e2", "psf_size", "n_epochs", "masked_frac", "is_bulge", "other_likelihood"};

bool contains(const std::string& text, const std::string& part) { return text.find(part) != std::string::npos; }

// Kills the run `pid` writing `out` with SIGKILL once it has committed rows (its checkpoint exists),
// and checks that the kill, not the run's end, stopped it.
void kill_after_a_commit(pid_t pid, const std::string& out, const std::string& err_path) {
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(120);
  while (!fs::exists(out + ".checkpoint") && std::chrono::steady_clock::now() < deadline)
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  std::this_thread::sleep_for(std::chrono::milliseconds(300));
  ASSERT_EQ(kill(pid, SIGKILL), 0);
  ASSERT_EQ(finish(pid, err_path).exit_code, 128 + SIGKILL) << "the run finished before it could be killed";
}

TEST_F(FitMeds, OneRowPerObjectInOrderForAnyThreadCount) {
  for (const char* threads : {"1", "2"}) {
    const RunResult r = run({"--meds", kSample + "/meds.fits", "-o", path(std::string("t") + threads + ".fits"),
                             "--threads", threads, "--set", "batch_size=5"});
    ASSERT_EQ(r.exit_code, 0) << r.err;
    EXPECT_TRUE(contains(r.err, "24 objects")) << r.err;
  }
  expect_tables_equal(path("t1.fits"), path("t2.fits"), kSurveyColumns);
  stampede::io::FitsFile tile = stampede::io::FitsFile::open_read(kSample + "/meds.fits");
  tile.move_to("object_data");
  const auto ids = tile.read_column("id"), numbers = tile.read_column("number"), ra = tile.read_column("ra");
  const auto id = column(path("t1.fits"), "id"), number = column(path("t1.fits"), "number"),
             ra_out = column(path("t1.fits"), "ra"), status = column(path("t1.fits"), "status"),
             n_epochs = column(path("t1.fits"), "n_epochs"), is_bulge = column(path("t1.fits"), "is_bulge"),
             radius = column(path("t1.fits"), "radius"), other = column(path("t1.fits"), "other_likelihood");
  ASSERT_EQ(id.size(), 24u);
  for (std::size_t i = 0; i < id.size(); ++i) {
    EXPECT_EQ(id[i], ids[i]);
    EXPECT_EQ(number[i], numbers[i]);
    EXPECT_EQ(ra_out[i], ra[i]);
    EXPECT_EQ(status[i], 0);
    EXPECT_EQ(n_epochs[i], 4);   // the single epochs, not the coadd
    EXPECT_EQ(is_bulge[i], -1);  // bd
    EXPECT_TRUE(std::isnan(other[i]));
    EXPECT_GT(radius[i], 0.05);  // arcsec: the tile's galaxies are 0.3-1 arcsec
    EXPECT_LT(radius[i], 3);
  }
}

// Metacal on a tile (issue 30): the metacal columns and gamma_fwhm for every object, the same
// table for any thread count, and shards that merge into it.
TEST_F(FitMeds, MetacalRowsAreTheSameForAnyThreadCountAndMergeFromShards) {
  const std::string tile = kSample + "/meds.fits";
  const std::vector<std::string> opts = {"--set", "metacal=true", "--set", "batch_size=3", "--quiet"};
  ASSERT_EQ(run(std::vector<std::string>{"--meds", tile, "-o", path("t2.fits"), "--threads", "2"} + opts).exit_code, 0);
  for (const char* shard : {"0/2", "1/2"}) {
    const RunResult r = run(std::vector<std::string>{"--meds", tile, "-o", path(std::string("s") + shard[0] + ".fits"),
                                                     "--threads", "1", "--shard", shard} + opts);
    ASSERT_EQ(r.exit_code, 0) << r.err;
  }
  const RunResult merged =
      finish(spawn({"-o", path("merged.fits"), path("s1.fits"), path("s0.fits"), "--quiet"}, path("merge.txt"), "merge"),
             path("merge.txt"));
  ASSERT_EQ(merged.exit_code, 0) << merged.err;
  std::vector<std::string> columns = kSurveyColumns;
  for (const char* c : {"R11", "R12", "R21", "R22", "e1_1p", "e2_1p", "snr_1p", "radius_1p", "e1_1m", "e2_1m", "snr_1m",
                        "radius_1m", "e1_2p", "e2_2p", "snr_2p", "radius_2p", "e1_2m", "e2_2m", "snr_2m", "radius_2m",
                        "gamma_fwhm"})
    columns.push_back(c);
  expect_tables_equal(path("t2.fits"), path("merged.fits"), columns);
  const auto r11 = column(path("t2.fits"), "R11"), r22 = column(path("t2.fits"), "R22"),
             gamma = column(path("t2.fits"), "gamma_fwhm"), psf = column(path("t2.fits"), "psf_size");
  ASSERT_EQ(r11.size(), 24u);
  int finite = 0;
  for (std::size_t i = 0; i < r11.size(); ++i) {
    finite += std::isfinite(r11[i]) && std::isfinite(r22[i]);
    // arcsec, against the PSF's Gaussian-equivalent FWHM (which overstates a Moffat's): of its scale.
    EXPECT_GT(gamma[i], 0.5 * 0.263 * 2.3548 * psf[i]) << i;
    EXPECT_LT(gamma[i], 2.0 * 0.263 * 2.3548 * psf[i]) << i;
  }
  EXPECT_EQ(finite, 24);
}

TEST_F(FitMeds, KillNineThenResumeEqualsUninterruptedRun) {
  const std::vector<std::string> opts = {"--set", "batch_size=1", "--threads", "1", "--quiet"};
  const std::string tile = kSample + "/meds.fits";
  ASSERT_EQ(run(std::vector<std::string>{"--meds", tile, "-o", path("full.fits")} + opts).exit_code, 0);
  const std::string out = path("resumed.fits");
  const pid_t pid = spawn(std::vector<std::string>{"--meds", tile, "-o", out} + opts, path("stderr.txt"));
  kill_after_a_commit(pid, out, path("stderr.txt"));
  if (::testing::Test::HasFatalFailure()) return;
  ASSERT_FALSE(fs::exists(out));
  const RunResult resumed = run(std::vector<std::string>{"--meds", tile, "-o", out, "--resume"} + opts);
  ASSERT_EQ(resumed.exit_code, 0) << resumed.err;
  expect_tables_equal(path("full.fits"), out, kSurveyColumns);
}

// Issue 31: the PSFEx models a run reads are part of it: one replaced between kill and resume is
// refused (no table with two PSFs), and none can be an output of the run.
TEST_F(FitMeds, PsfexModelsAreFingerprintedAndProtected) {
  fs::create_directories(path("tile"));
  fs::copy(kSample + "/psfex", path("tile/psfex"));
  const std::string tile = path("tile/meds.fits");
  fs::copy_file(kSample + "/meds.fits", tile);
  const RunResult over = run({"--meds", tile, "-o", path("tile/psfex/se_e1.psf"), "--overwrite", "--quiet"});
  EXPECT_EQ(over.exit_code, 1);
  EXPECT_TRUE(contains(over.err, "is the PSFEx model")) << over.err;
  const std::vector<std::string> opts = {"--set", "batch_size=1", "--threads", "1", "--quiet"};
  const std::string out = path("resumed.fits");
  const pid_t pid = spawn(std::vector<std::string>{"--meds", tile, "-o", out} + opts, path("stderr.txt"));
  kill_after_a_commit(pid, out, path("stderr.txt"));
  if (::testing::Test::HasFatalFailure()) return;
  fs::copy_file(path("tile/psfex/se_e2.psf"), path("tile/psfex/se_e1.psf"), fs::copy_options::overwrite_existing);
  const RunResult resumed = run(std::vector<std::string>{"--meds", tile, "-o", out, "--resume"} + opts);
  EXPECT_EQ(resumed.exit_code, 1);
  EXPECT_TRUE(contains(resumed.err, "was written by a different run")) << resumed.err;
  EXPECT_TRUE(contains(resumed.err, "se_e1.psf")) << resumed.err;
}

// A resume that is another run is refused by what differs, not by a line at the same place of the
// fingerprint: other band names (the partial used to be "corrupt: column 38 is not 'n_epochs_i'")
// and another meds_psf_dir (other PSFEx files: the message compared unrelated lines).
TEST_F(FitMeds, AResumeOfAnotherRunNamesWhatDiffers) {
  const std::string sim = path("sim");
  RunResult r = stampede::testing::finish(
      spawn({"meds", "--out", sim, "--objects", "64", "--epochs", "1", "--noise-free", "--bands", "g,r"}, path("sim.txt"),
            "sim"),
      path("sim.txt"));
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const std::vector<std::string> tiles = {"--meds", sim + "/g/meds.fits", "--meds", sim + "/r/meds.fits"};
  const std::vector<std::string> opts = {"--set", "batch_size=1", "--threads", "1", "--quiet"};
  const std::string out = path("out.fits");
  const pid_t pid = spawn(tiles + std::vector<std::string>{"--bands", "g,r", "-o", out} + opts, path("stderr.txt"));
  kill_after_a_commit(pid, out, path("stderr.txt"));
  if (::testing::Test::HasFatalFailure()) return;
  const RunResult bands = run(tiles + std::vector<std::string>{"--bands", "g,i", "-o", out, "--resume"} + opts);
  EXPECT_EQ(bands.exit_code, 1);
  EXPECT_TRUE(contains(bands.err, "was written by a different run (input or configuration changed): it records "
                                  "'bands=g,r', this run has 'bands=g,i'"))
      << bands.err;
  fs::create_directories(path("elsewhere"));
  const RunResult psf = run(tiles + std::vector<std::string>{"--bands", "g,r", "-o", out, "--resume", "--set",
                                                             "meds_psf_dir=" + path("elsewhere")} + opts);
  EXPECT_EQ(psf.exit_code, 1);
  EXPECT_TRUE(contains(psf.err, "it records 'meds_psf_dir=', this run has 'meds_psf_dir=" + path("elsewhere") + "'"))
      << psf.err;
  ASSERT_TRUE(fs::exists(out + ".partial")) << "a refused resume keeps the run resumable";
  const RunResult resumed = run(tiles + std::vector<std::string>{"--bands", "g,r", "-o", out, "--resume"} + opts);
  EXPECT_EQ(resumed.exit_code, 0) << resumed.err;
}

// Issue 31: grid options --meds does not use are named, and a run in which no object could be
// fitted (here: PSFEx models looked for in the wrong directory) says so and exits non-zero.
TEST_F(FitMeds, UnusedOptionsAreNamedAndARunWithNothingFittedFails) {
  const RunResult r = run({"--meds", kSample + "/meds.fits", "-o", path("none.fits"), "--set", "meds_psf=psfex", "--set",
                           "meds_psf_dir=" + path("nowhere"), "--set", "noise_sigma=2", "--set", "stamp_size=32",
                           "--quiet"});
  EXPECT_EQ(r.exit_code, 3) << r.err;
  EXPECT_TRUE(contains(r.err, "option 'noise_sigma' is not used with --meds")) << r.err;
  EXPECT_TRUE(contains(r.err, "option 'stamp_size' is not used with --meds")) << r.err;
  EXPECT_TRUE(contains(r.err, "none of the 24 objects could be fitted (status: psf_failure=24)")) << r.err;
  EXPECT_EQ(column(path("none.fits"), "id").size(), 24u);  // the flagged rows are kept
}

// Issue 31: a broken zero point (NaN, 1e30, -100) drops that image's cutouts with a flag and a
// warning naming image_info, magzp and the row; n_epochs counts the epochs used.
TEST_F(FitMeds, ABadZeroPointDropsItsCutoutsWithAFlag) {
  for (double bad : {static_cast<double>(NAN), 1e30, -100.0}) {
    SCOPED_TRACE(bad);
    const std::string tile = path("tile.fits");
    fs::copy_file(kSample + "/meds.fits", tile, fs::copy_options::overwrite_existing);
    stampede::testing::MedsEditor(tile).set_cell("image_info", "magzp", 2, 0, bad);
    const RunResult r = run({"--meds", tile, "-o", path("bad.fits"), "--overwrite", "--set", "meds_psf_dir=" + kSample});
    ASSERT_EQ(r.exit_code, 0) << r.err;
    EXPECT_TRUE(contains(r.err, "image_info row 2: magzp = ")) << r.err;
    const auto n_epochs = column(path("bad.fits"), "n_epochs"), flags = column(path("bad.fits"), "flags"),
               status = column(path("bad.fits"), "status");
    for (std::size_t i = 0; i < n_epochs.size(); ++i) {
      EXPECT_EQ(n_epochs[i], 3) << i;  // image_info row 2 is one of the four single epochs
      EXPECT_NE(static_cast<long long>(flags[i]) & stampede::kFlagBadZeroPoint, 0) << i;
      EXPECT_EQ(status[i], 0) << i;
    }
  }
}

// Issue 31: a tile that repeats an id is refused naming the column and both rows (grids and
// catalogues refuse them too); a cutout whose object centre lies outside it is a dropped cutout
// with a warning naming the columns, not a silent fit.
TEST_F(FitMeds, RepeatedIdsAndCentresOutsideTheCutoutAreCaught) {
  const std::string tile = path("tile.fits");
  fs::copy_file(kSample + "/meds.fits", tile);
  stampede::testing::MedsEditor(tile).set_cell("object_data", "cutout_row", 3, 1, 1e6);
  const RunResult far = run({"--meds", tile, "-o", path("far.fits"), "--set", "meds_psf_dir=" + kSample});
  ASSERT_EQ(far.exit_code, 0) << far.err;
  EXPECT_TRUE(contains(far.err, "'cutout_row'[1]")) << far.err;
  EXPECT_TRUE(contains(far.err, "outside its")) << far.err;
  EXPECT_EQ(column(path("far.fits"), "n_epochs")[3], 3);
  long long id0 = 0;
  {
    stampede::io::FitsFile f = stampede::io::FitsFile::open_read(tile);
    f.move_to("object_data");
    std::vector<long long> one(1);
    f.read_column_rows("id", 0, one);
    id0 = one[0];
  }
  stampede::testing::MedsEditor(tile).set_cell("object_data", "id", 5, 0, id0);
  const RunResult dup = run({"--meds", tile, "-o", path("dup.fits"), "--set", "meds_psf_dir=" + kSample});
  EXPECT_EQ(dup.exit_code, 1);
  EXPECT_TRUE(contains(dup.err, "column 'id' holds " + std::to_string(id0) + " in rows 0 and 5")) << dup.err;
  EXPECT_FALSE(fs::exists(path("dup.fits")));
}

TEST_F(FitMeds, ABadFileIsAnErrorNamingTheFileHduAndColumn) {
  const std::string tile = path("tile.fits");
  fs::copy_file(kSample + "/meds.fits", tile);
  stampede::testing::MedsEditor(tile).delete_column("object_data", "start_row");
  RunResult r = run({"--meds", tile, "-o", path("out.fits"), "--set", "meds_psf_dir=" + kSample});
  EXPECT_EQ(r.exit_code, 1) << r.err;
  EXPECT_TRUE(contains(r.err, "tile.fits")) << r.err;
  EXPECT_TRUE(contains(r.err, "'object_data'")) << r.err;
  EXPECT_TRUE(contains(r.err, "no column 'start_row'")) << r.err;
  EXPECT_FALSE(fs::exists(path("out.fits")));
  EXPECT_FALSE(fs::exists(path("out.fits.partial")));

  fs::remove(tile);
  fs::copy_file(kSample + "/meds.fits", tile);
  stampede::testing::MedsEditor(tile).delete_hdu("image_cutouts");
  r = run({"--meds", tile, "-o", path("out.fits")});
  EXPECT_EQ(r.exit_code, 1) << r.err;
  EXPECT_TRUE(contains(r.err, "tile.fits")) << r.err;
  EXPECT_TRUE(contains(r.err, "'image_cutouts'")) << r.err;

  r = run({"--meds", path("none.fits"), "-o", path("out.fits")});
  EXPECT_EQ(r.exit_code, 1) << r.err;
  EXPECT_TRUE(contains(r.err, "none.fits")) << r.err;

  r = run({"--meds", kSample + "/meds.fits", "-o", path("out.fits"), "--set", "renderer=upsampled"});
  EXPECT_EQ(r.exit_code, 1) << r.err;
  EXPECT_TRUE(contains(r.err, "'renderer'")) << r.err;
  r = run({"--meds", kSample + "/meds.fits", "-o", path("out.fits"), "--set", "meds_psf=cutouts"});
  EXPECT_EQ(r.exit_code, 1) << r.err;
  EXPECT_TRUE(contains(r.err, "'meds_psf' = 'cutouts'")) << r.err;
  EXPECT_TRUE(contains(r.err, "no HDU 'psf'")) << r.err;
  r = run({"--meds", kSample + "/meds.fits", "-o", path("out.fits"), "--set", "meds_min_unmasked_fraction=2"});
  EXPECT_EQ(r.exit_code, 1) << r.err;
  EXPECT_TRUE(contains(r.err, "meds_min_unmasked_fraction")) << r.err;
}

// Bad objects and cutouts: every row is still written, flagged, and the warnings name the object,
// the column and, for PSFs, the missing file.
TEST_F(FitMeds, BadObjectsAreFlaggedRowsNeverMissingOnes) {
  const std::string tile = path("tile.fits");
  fs::copy_file(kSample + "/meds.fits", tile);
  stampede::testing::MedsEditor e(tile);
  e.set_cell("object_data", "box_size", 5, 0, 0LL);                    // zero box: the object
  for (int k = 1; k < 5; ++k) e.set_cell("object_data", "start_row", 23, k, 276480LL - 48 * 48 + 1);  // past the array
  for (int k = 1; k < 5; ++k) {                                          // zero-determinant Jacobians
    e.set_cell("object_data", "dudrow", 2, k, 0.0);
    e.set_cell("object_data", "dudcol", 2, k, 0.0);
  }
  e.set_cell("object_data", "start_row", 7, 2, 276480LL - 48 * 48 + 1);  // one bad cutout of four
  const RunResult r = run({"--meds", tile, "-o", path("out.fits"), "--set", "meds_psf_dir=" + kSample});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_TRUE(contains(r.err, "row 5: ")) << r.err;
  EXPECT_TRUE(contains(r.err, "'box_size' = 0")) << r.err;
  EXPECT_TRUE(contains(r.err, "'start_row'[1]")) << r.err;
  EXPECT_TRUE(contains(r.err, "no inverse")) << r.err;
  const auto flags = column(path("out.fits"), "flags"), status = column(path("out.fits"), "status"),
             n_epochs = column(path("out.fits"), "n_epochs");
  ASSERT_EQ(flags.size(), 24u);
  for (int row : {2, 5, 23}) {
    EXPECT_TRUE(static_cast<std::uint32_t>(flags[row]) & stampede::kFlagNoUsableEpoch) << row;
    EXPECT_NE(status[row], 0) << row;
  }
  EXPECT_EQ(n_epochs[7], 3);
  EXPECT_EQ(status[7], 0);
  int ok = 0;
  for (double s : status) ok += s == 0;
  EXPECT_EQ(ok, 21);

  // No PSFEx models where meds_psf_dir points: every row flagged, the warning names a file, and
  // with nothing fitted the run fails (exit 3) with the table of flagged rows written.
  const RunResult none = run({"--meds", tile, "-o", path("nopsf.fits"), "--set", "meds_psf_dir=" + path("")});
  ASSERT_EQ(none.exit_code, 3) << none.err;
  EXPECT_TRUE(contains(none.err, ".psf")) << none.err;
  const auto psf_flags = column(path("nopsf.fits"), "flags"), psf_status = column(path("nopsf.fits"), "status");
  ASSERT_EQ(psf_flags.size(), 24u);
  for (std::size_t i = 0; i < psf_flags.size(); ++i) {
    if (i == 2 || i == 5 || i == 23) continue;
    EXPECT_TRUE(static_cast<std::uint32_t>(psf_flags[i]) & stampede::kFlagPsfFailure) << i;
    EXPECT_TRUE(static_cast<std::uint32_t>(psf_flags[i]) & stampede::kFlagNoUsableEpoch) << i;
    EXPECT_EQ(psf_status[i], static_cast<int>(stampede::FitStatus::kPsfFailure)) << i;
  }
}

// Issue 43 item 11: one epoch's PSFEx model missing drops that cutout, not the object. The rows
// are fitted on their other three epochs, say so (flag 8388608 and the warning naming the file)
// and stay usable for shear; an object whose other cutouts are unusable too has no epoch left and
// is a PSF failure, excluded.
TEST_F(FitMeds, AMissingPsfexModelDropsItsCutoutsNotTheObjects) {
  fs::create_directories(path("tile"));
  fs::copy(kSample + "/psfex", path("tile/psfex"));
  fs::remove(path("tile/psfex/se_e2.psf"));  // image_info row 2, one of the four single epochs
  const std::string tile = path("tile/meds.fits");
  fs::copy_file(kSample + "/meds.fits", tile);
  const int lost = 11;  // its cutouts from images 1, 3 and 4 point past the pixel array
  for (int k : {1, 3, 4}) stampede::testing::MedsEditor(tile).set_cell("object_data", "start_row", lost, k, 276480LL - 48 * 48 + 1);
  const RunResult r = run({"--meds", tile, "-o", path("out.fits")});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_TRUE(contains(r.err, "se_e2.psf")) << r.err;
  const auto flags = column(path("out.fits"), "flags"), status = column(path("out.fits"), "status"),
             n_epochs = column(path("out.fits"), "n_epochs");
  ASSERT_EQ(flags.size(), 24u);
  for (std::size_t i = 0; i < flags.size(); ++i) {
    const auto f = static_cast<std::uint32_t>(flags[i]);
    EXPECT_TRUE(f & stampede::kFlagPsfCutoutDropped) << i;
    if (static_cast<int>(i) == lost) {
      EXPECT_EQ(n_epochs[i], 0);
      EXPECT_TRUE(f & stampede::kFlagNoUsableEpoch);
      EXPECT_TRUE(f & stampede::kFlagPsfFailure);
      EXPECT_EQ(status[i], static_cast<int>(stampede::FitStatus::kPsfFailure));
      EXPECT_FALSE(stampede::usable_for_shear(static_cast<stampede::FitStatus>(status[i]), f));
      continue;
    }
    EXPECT_EQ(n_epochs[i], 3) << i;
    EXPECT_EQ(status[i], 0) << i;
    EXPECT_FALSE(f & (stampede::kFlagPsfFailure | stampede::kFlagNoUsableEpoch)) << i;
    EXPECT_TRUE(stampede::usable_for_shear(stampede::FitStatus::kOk, f)) << i;
  }
}

// The workflow a shear tester runs: two simulated tiles, fitted, measured by `stampede metrics`.
TEST_F(FitMeds, SimulatedTilesFittedAndMeasuredByMetrics) {
  std::vector<std::string> metrics_args;
  const char* shears[2] = {"0.03,-0.02", "-0.02,0.035"};
  for (int k = 0; k < 2; ++k) {
    const std::string dir = path(k == 0 ? "t0" : "t1");
    RunResult r = stampede::testing::finish(
        spawn({"meds", "--out", dir, "--objects", "8", "--noise-free", "--shear", shears[k], "--seed", std::to_string(9 + k)},
              path("sim.txt"), "sim"),
        path("sim.txt"));
    ASSERT_EQ(r.exit_code, 0) << r.err;
    r = run({"--meds", dir + "/meds.fits", "-o", dir + "/fit.fits", "--quiet"});
    ASSERT_EQ(r.exit_code, 0) << r.err;
    metrics_args.insert(metrics_args.end(), {"--fit", dir + "/fit.fits", "--truth", dir + "/truth.fits"});
  }
  const RunResult m =
      stampede::testing::finish(spawn(metrics_args, path("metrics.txt"), "metrics", path("out.txt")), path("metrics.txt"));
  ASSERT_EQ(m.exit_code, 0) << m.err;
  std::ifstream out(path("out.txt"));
  const std::string text((std::istreambuf_iterator<char>(out)), {});
  double m1 = NAN, c1 = NAN;
  const std::size_t at = text.find("m1 = ");
  ASSERT_NE(at, std::string::npos) << text;
  ASSERT_EQ(std::sscanf(text.c_str() + at, "m1 = %lf +- %*f c1 = %lf", &m1, &c1), 2) << text;
  // Noise-free, against the applied g: only the 4 ring pairs' own O(g e^2) response remains.
  EXPECT_LT(std::abs(m1), 0.1) << text;
  EXPECT_LT(std::abs(c1), 5e-3) << text;

  // Each table records its tile's simulation (SIMID, as INSETID), which the truth file carries too:
  // the other simulation's truth (same ids, same row count) is refused by name.
  std::string simid[2];
  for (int k = 0; k < 2; ++k) {
    const std::string dir = path(k == 0 ? "t0" : "t1");
    stampede::io::FitsFile truth = stampede::io::FitsFile::open_read(dir + "/truth.fits");
    simid[k] = truth.key_string("SIMID");
    EXPECT_EQ(simid[k].size(), 16u) << simid[k];
    stampede::io::FitsFile tile = stampede::io::FitsFile::open_read(dir + "/meds.fits");
    EXPECT_EQ(tile.key_string("SIMID"), simid[k]);
    stampede::io::FitsFile fit = stampede::io::FitsFile::open_read(dir + "/fit.fits");
    fit.move_to("RESULTS");
    EXPECT_EQ(fit.key_string("INSETID"), "SIMID=" + simid[k]);
  }
  EXPECT_NE(simid[0], simid[1]);
  const std::string t0 = path("t0"), t1 = path("t1");
  const RunResult swapped = stampede::testing::finish(
      spawn({"--fit", t0 + "/fit.fits", "--truth", t1 + "/truth.fits", "--fit", t1 + "/fit.fits", "--truth",
             t0 + "/truth.fits"},
            path("metrics.txt"), "metrics", path("out.txt")),
      path("metrics.txt"));
  EXPECT_EQ(swapped.exit_code, 1) << swapped.err;
  EXPECT_TRUE(contains(swapped.err, t0 + "/fit.fits[HDU 1 'RESULTS'] is a fit of set 'SIMID=" + simid[0] +
                                        "' (INSETID), but " + t1 + "/truth.fits is the truth of set 'SIMID=" + simid[1] + "'"))
      << swapped.err;

  // Tiles of two simulations share ids and positions, but are not two bands of one set of galaxies.
  const RunResult mixed =
      run({"--meds", t0 + "/meds.fits", "--meds", t1 + "/meds.fits", "--bands", "g,r", "-o", path("mixed.fits"), "--quiet"});
  EXPECT_EQ(mixed.exit_code, 1) << mixed.err;
  EXPECT_FALSE(fs::exists(path("mixed.fits")));
  EXPECT_TRUE(contains(mixed.err, "--meds '" + t1 + "/meds.fits' (band r) is of simulation 'SIMID=" + simid[1] +
                                      "' but --meds '" + t0 + "/meds.fits' (band g) of 'SIMID=" + simid[0] + "'"))
      << mixed.err;
}

// The bands of one `sim meds --bands` simulation share its SIMID: fitted together, and each band's
// truth is the fit's.
TEST_F(FitMeds, TheBandsOfOneSimulationShareItsIdentity) {
  const std::string dir = path("bands");
  RunResult r = stampede::testing::finish(
      spawn({"meds", "--out", dir, "--objects", "4", "--epochs", "1", "--noise-free", "--bands", "g,r"}, path("sim.txt"),
            "sim"),
      path("sim.txt"));
  ASSERT_EQ(r.exit_code, 0) << r.err;
  r = run({"--meds", dir + "/g/meds.fits", "--meds", dir + "/r/meds.fits", "--bands", "g,r", "-o", path("gr.fits"),
           "--quiet"});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  for (const char* band : {"g", "r"}) {
    const RunResult m = stampede::testing::finish(
        spawn({"--fit", path("gr.fits"), "--truth", dir + "/" + band + "/truth.fits"}, path("metrics.txt"), "metrics",
              path("out.txt")),
        path("metrics.txt"));
    EXPECT_EQ(m.exit_code, 0) << band << ": " << m.err;
  }
}

}  // namespace
