// `mpirun -n 2 stampede-mpi fit`: the one table equals a single process's (every column but
// time_us); a job whose worker rank is killed mid-run resumes to the same table; a rank-0 error is
// an error of the job (no hang). Run as root in CI: OMPI_ALLOW_RUN_AS_ROOT is set for mpirun.
#include <gtest/gtest.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <sstream>
#include <string>
#include <thread>
#include <utility>
#include <vector>

#include "io/catalog_reader.hpp"
#include "io/fits_file.hpp"
#include "support/command_runner.hpp"
#include "support/fit_output.hpp"
#include "support/scratch_dir.hpp"

namespace {

using namespace stampede;
using stampede::testing::expect_tables_equal;
using stampede::testing::operator+;
namespace fs = std::filesystem;

const std::string kInput = std::string(STAMPEDE_DATA_DIR) + "/galsim-great08-mini/snr40/set_0.fits";
const std::vector<std::string> kOptions = {"--set", "renderer=exact", "--set", "psf_beta=3", "--set", "psf_fwhm=2.85",
                                           "--set", "psf_e2=0.05",   "--set", "noise_sigma=1", "--set",  "batch_size=4",
                                           "--threads", "1", "--quiet"};

// `mpirun -n RANKS stampede-mpi COMMAND ARGS...`, stderr to err_path.
pid_t spawn_mpi(int ranks, std::vector<std::string> args, const std::string& err_path, const std::string& command = "fit") {
  const pid_t pid = fork();
  if (pid == 0) {
    FILE* e = std::fopen(err_path.c_str(), "w");
    if (e) dup2(fileno(e), 2);
    setenv("OMPI_ALLOW_RUN_AS_ROOT", "1", 1);
    setenv("OMPI_ALLOW_RUN_AS_ROOT_CONFIRM", "1", 1);
    // ASan builds: OpenMPI's own leaks (tests/lsan.supp) are known by their whole stack, which
    // ASan's fast unwinder loses in OpenMPI's plugins. No effect on other builds.
    setenv("ASAN_OPTIONS", "fast_unwind_on_malloc=0", 0);
    std::vector<std::string> all = {STAMPEDE_MPIEXEC, "-n", std::to_string(ranks), "--oversubscribe",
                                    STAMPEDE_MPI_BINARY, command};
    all.insert(all.end(), args.begin(), args.end());
    std::vector<char*> argv;
    for (auto& a : all) argv.push_back(a.data());
    argv.push_back(nullptr);
    execv(argv[0], argv.data());
    _exit(127);
  }
  return pid;
}

// The pid of the rank `rank` process of a job whose command line names `marker` (a unique path).
pid_t rank_pid(const std::string& marker, int rank) {
  for (const auto& entry : fs::directory_iterator("/proc")) {
    const std::string name = entry.path().filename();
    if (name.find_first_not_of("0123456789") != std::string::npos) continue;
    std::ifstream cmd(entry.path() / "cmdline"), env(entry.path() / "environ");
    std::stringstream c, e;
    c << cmd.rdbuf();
    e << env.rdbuf();
    const std::string cmdline = c.str(), environ_text = e.str();
    if (cmdline.find(marker) == std::string::npos || cmdline.find("stampede-mpi") == std::string::npos) continue;
    if (cmdline.find("mpirun") != std::string::npos || cmdline.find("mpiexec") != std::string::npos) continue;
    if (environ_text.find("OMPI_COMM_WORLD_RANK=" + std::to_string(rank) + std::string(1, '\0')) != std::string::npos)
      return static_cast<pid_t>(std::stol(name));
  }
  return -1;
}

// Every numeric column of two RESULTS tables but time_us, bitwise (NaN equals NaN); at least one.
void expect_every_column_equal(const std::string& a, const std::string& b) {
  auto f = io::FitsFile::open_read(a);
  f.move_to("RESULTS");
  std::vector<std::string> names;
  for (long long k = 1, n = f.key_long("TFIELDS"); k <= n; ++k) {
    const std::string name = f.key_string("TTYPE" + std::to_string(k));
    if (name != "time_us" && f.column_repeat(name) == 1 && f.key_string("TFORM" + std::to_string(k)) != "1A")
      names.push_back(name);
  }
  ASSERT_GT(names.size(), 20u) << a;
  expect_tables_equal(a, b, names);
}

std::string read_bytes(const std::string& p) {
  std::ifstream in(p, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

class MpiDriver : public ::testing::Test {
 protected:
  std::string path(const std::string& name) const { return scratch.path(name); }
  stampede::testing::ScratchDir scratch{"stampede_mpi_"};
};

TEST_F(MpiDriver, TwoRanksWriteTheSingleProcessTable) {
  ASSERT_EQ(stampede::testing::finish(stampede::testing::spawn((std::vector<std::string>{kInput, "-o", path("single.fits")} + kOptions),
                                                               path("single.txt")),
                                      path("single.txt"))
                .exit_code,
            0);
  const auto r = stampede::testing::finish(spawn_mpi(2, (std::vector<std::string>{kInput, "-o", path("mpi.fits")} + kOptions), path("mpi.txt")),
                                           path("mpi.txt"));
  ASSERT_EQ(r.exit_code, 0) << r.err;
  expect_tables_equal(path("single.fits"), path("mpi.fits"));
  // One rank (`mpirun -n 1`): rank 0 fits every batch itself.
  const auto one = stampede::testing::finish(spawn_mpi(1, (std::vector<std::string>{kInput, "-o", path("one.fits")} + kOptions), path("one.txt")),
                                             path("one.txt"));
  ASSERT_EQ(one.exit_code, 0) << one.err;
  expect_tables_equal(path("single.fits"), path("one.fits"));
}

TEST_F(MpiDriver, AKilledWorkerRankThenResumeUnderAnotherRankCountGivesTheSameTable) {
  ASSERT_EQ(stampede::testing::finish(stampede::testing::spawn((std::vector<std::string>{kInput, "-o", path("single.fits")} + kOptions),
                                                               path("single.txt")),
                                      path("single.txt"))
                .exit_code,
            0);
  const std::string out = path("killed.fits");
  const pid_t job = spawn_mpi(2, (std::vector<std::string>{kInput, "-o", out} + kOptions), path("killed.txt"));
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(120);
  while (!fs::exists(out + ".checkpoint") && std::chrono::steady_clock::now() < deadline)
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  std::this_thread::sleep_for(std::chrono::milliseconds(800));
  const pid_t worker = rank_pid(out, 1);
  ASSERT_GT(worker, 0) << "no rank 1 found";
  ASSERT_EQ(kill(worker, SIGKILL), 0);
  const auto killed = stampede::testing::finish(job, path("killed.txt"));
  ASSERT_NE(killed.exit_code, 0) << "the job finished before its worker could be killed";
  ASSERT_FALSE(fs::exists(out));
  ASSERT_TRUE(fs::exists(out + ".checkpoint"));
  // Resumed by a job of 3 ranks: a fit's one table is rank 0's, so the rank count is not part of
  // the run and the job continues where the killed one stopped (metadetect's per-rank parts refuse
  // another count: RefusesTheOutputsTheSingleProcessRefuses).
  const auto resumed = stampede::testing::finish(spawn_mpi(3, (std::vector<std::string>{kInput, "-o", out, "--resume"} + kOptions),
                                                           path("resumed.txt")),
                                                 path("resumed.txt"));
  ASSERT_EQ(resumed.exit_code, 0) << resumed.err;
  expect_tables_equal(path("single.fits"), out);
}

TEST_F(MpiDriver, RanksTakingWholeFilesWriteEachFilesTable) {
  // Three small sets (6 x 6 stamps), and a list naming them.
  ASSERT_EQ(stampede::testing::finish(stampede::testing::spawn({"great08", "--out", path("sets"), "--sets", "3", "--grid",
                                                                "6", "--snr", "20"},
                                                               path("sim.txt"), "sim"),
                                      path("sim.txt"))
                .exit_code,
            0);
  std::ofstream(path("tiles.txt")) << path("sets/set_0.fits") << "\n" << path("sets/set_1.fits") << "\n"
                                   << path("sets/set_0.fits.gz") << "  # the same name twice\n";
  auto r = stampede::testing::finish(spawn_mpi(2, (std::vector<std::string>{"--input-list", path("tiles.txt"), "-o", path("out")} + kOptions),
                                               path("dup.txt")),
                                     path("dup.txt"));
  EXPECT_NE(r.exit_code, 0);
  EXPECT_NE(r.err.find("tiles.txt:3: "), std::string::npos) << r.err;  // refused before any fit
  std::ofstream(path("tiles.txt")) << "# tonight\n" << path("sets/set_0.fits") << "\n" << path("sets/set_1.fits") << "\n"
                                   << path("sets/set_2.fits") << "\n";
  r = stampede::testing::finish(spawn_mpi(2, (std::vector<std::string>{"--input-list", path("tiles.txt"), "-o", path("out")} + kOptions),
                                          path("list.txt")),
                                path("list.txt"));
  ASSERT_EQ(r.exit_code, 0) << r.err;
  for (int k : {0, 1, 2}) {
    const std::string single = path("single" + std::to_string(k) + ".fits");
    const std::string input = path("sets/set_" + std::to_string(k) + ".fits");
    ASSERT_EQ(stampede::testing::finish(stampede::testing::spawn((std::vector<std::string>{input, "-o", single} + kOptions), path("s.txt")),
                                        path("s.txt"))
                  .exit_code,
              0);
    expect_tables_equal(single, path("out/set_" + std::to_string(k) + "_fit.fits"));
  }
  // --resume skips a complete output of the same run (its RUNFP), and refuses another run's
  // (issue 31: it once skipped outputs fitted with other options).
  std::vector<std::string> loud = kOptions;
  loud.pop_back();  // not --quiet: the skip is reported
  r = stampede::testing::finish(
      spawn_mpi(2, std::vector<std::string>{"--input-list", path("tiles.txt"), "-o", path("out"), "--resume"} + loud,
                path("again.txt")),
      path("again.txt"));
  EXPECT_EQ(r.exit_code, 0) << r.err;
  EXPECT_NE(r.err.find("set_1_fit.fits is complete, skipped"), std::string::npos) << r.err;
  r = stampede::testing::finish(
      spawn_mpi(2, std::vector<std::string>{"--input-list", path("tiles.txt"), "-o", path("out"), "--resume", "--threads", "1"},
                path("other.txt")),
      path("other.txt"));
  EXPECT_NE(r.exit_code, 0);
  EXPECT_NE(r.err.find("is complete but was written by another run (RUNFP = '"), std::string::npos) << r.err;
}

TEST_F(MpiDriver, AnErrorOnRankZeroEndsTheJob) {
  const auto r = stampede::testing::finish(
      spawn_mpi(2, (std::vector<std::string>{path("missing.fits"), "-o", path("x.fits")} + kOptions), path("err.txt")), path("err.txt"));
  EXPECT_NE(r.exit_code, 0);
  EXPECT_NE(r.err.find("missing.fits"), std::string::npos) << r.err;
}

// Issue 31: every option family the driver accepts gives, under mpirun -n 2, the single process's
// table bit for bit (a worker that built its fitter from its own recipe once wrote plain fits into a
// metacal table). Input lists: RanksTakingWholeFilesWriteEachFilesTable.
TEST_F(MpiDriver, EveryOptionFamilyUnderTwoRanksEqualsOneProcess) {
  ASSERT_EQ(stampede::testing::finish(stampede::testing::spawn({"great08", "--out", path("sets"), "--sets", "1", "--grid",
                                                                "6", "--snr", "40", "--seed", "3", "--stamp", "39"},
                                                               path("sim.txt"), "sim"),
                                      path("sim.txt"))
                .exit_code,
            0);
  const std::string set = path("sets/set_0.fits");
  {  // a sampled round Gaussian PSF of sigma 1.2 px
    std::vector<double> psf(21 * 21);
    for (int y = 0; y < 21; ++y)
      for (int x = 0; x < 21; ++x) psf[y * 21 + x] = std::exp(-((x - 10) * (x - 10) + (y - 10) * (y - 10)) / (2 * 1.44));
    io::FitsFile::create(path("psf.fits"), true).write_image(21, 21, psf);
  }
  {  // every stamp of the grid as a catalogue row, each with its own Moffat PSF
    std::ofstream cat(path("cat.txt"));
    cat << "# id x y psf_beta psf_fwhm psf_e1 psf_e2\n";
    for (int k = 0; k < 36; ++k)
      cat << 500 + k << " " << (k % 6) * 39 + 20 << " " << (k / 6) * 39 + 20 << " " << 2.5 + 0.05 * k << " "
          << 2.6 + 0.02 * k << " " << 0.001 * (k - 18) << " " << 0.04 - 0.002 * k << "\n";
  }
  const std::vector<std::string> base = {"--set", "noise_sigma=1", "--set", "batch_size=4", "--threads", "1", "--quiet"};
  const std::vector<std::pair<std::string, std::vector<std::string>>> families = {
      {"plain", {}},
      {"metacal", {"--set", "metacal=true"}},
      {"image_psf", {"--set", "psf_input=image", "--set", "psf_image=" + path("psf.fits")}},
      {"catalogue", {"--catalog", path("cat.txt"), "--set", "psf_input=moffat_catalog"}},
      {"shard", {"--shard", "1/2"}},
      {"upsampled", {"--set", "renderer=upsampled", "--set", "upsampling=3"}},
  };
  for (const auto& [name, options] : families) {
    SCOPED_TRACE(name);
    const std::string single = path(name + "_single.fits"), mpi = path(name + "_mpi.fits");
    const auto s = stampede::testing::finish(
        stampede::testing::spawn(std::vector<std::string>{set, "-o", single} + base + options, path("s.txt")),
        path("s.txt"));
    ASSERT_EQ(s.exit_code, 0) << s.err;
    const auto m = stampede::testing::finish(spawn_mpi(2, std::vector<std::string>{set, "-o", mpi} + base + options, path("m.txt")),
                                             path("m.txt"));
    ASSERT_EQ(m.exit_code, 0) << m.err;
    expect_every_column_equal(single, mpi);
  }
}

// Measured FFTW plans are chosen per process, so ranks could round differently: refused by name.
TEST_F(MpiDriver, MeasuredFftPlansAreRefused) {
  const auto r = stampede::testing::finish(
      spawn_mpi(2, std::vector<std::string>{kInput, "-o", path("w.fits"), "--set", "fft_wisdom=" + path("w.wisdom")} + kOptions,
                path("err.txt")),
      path("err.txt"));
  EXPECT_NE(r.exit_code, 0);
  EXPECT_NE(r.err.find("option 'fft_wisdom'"), std::string::npos) << r.err;
  EXPECT_FALSE(fs::exists(path("w.fits")));
}

// The workers fit the pixels they are sent and a survey batch carries only row numbers: a MEDS tile
// is refused by name (and nothing is written), never fitted wrong on the other ranks.
// MEDS tiles over ranks: each batch carries its objects' cutouts, weights, frames and PSF images
// (io/meds_object_source fills them in rank 0's serial stage), so a worker fits them without the
// tile. One band with PSFEx models, and three bands with metacal, equal one process's table.
TEST_F(MpiDriver, MedsTilesOverTwoRanksWriteTheSingleProcessTable) {
  for (const auto& [dir, extra] : std::vector<std::pair<std::string, std::vector<std::string>>>{
           {"one", {"--objects", "24", "--neighbours", "0.5", "--bad-columns", "0.3"}},
           {"three", {"--objects", "12", "--bands", "g,r,i"}}}) {
    const auto sim = stampede::testing::finish(
        stampede::testing::spawn(std::vector<std::string>{"meds", "--out", path(dir)} + extra, path("sim.txt"), "sim"),
        path("sim.txt"));
    ASSERT_EQ(sim.exit_code, 0) << sim.err;
  }
  const std::vector<std::string> one = {"--meds", path("one/meds.fits"), "--set", "batch_size=4", "--threads", "1",
                                        "--quiet"};
  const std::vector<std::string> three = {"--meds", path("three/g/meds.fits"), "--meds", path("three/r/meds.fits"),
                                          "--meds", path("three/i/meds.fits"), "--bands", "g,r,i", "--set", "metacal=true",
                                          "--set", "batch_size=2", "--threads", "1", "--quiet"};
  for (const auto& [name, args] : std::vector<std::pair<std::string, std::vector<std::string>>>{{"one", one}, {"three", three}}) {
    const auto single = stampede::testing::finish(
        stampede::testing::spawn(std::vector<std::string>{"-o", path(name + "_single.fits")} + args, path("single.txt")),
        path("single.txt"));
    ASSERT_EQ(single.exit_code, 0) << single.err;
    const auto r = stampede::testing::finish(spawn_mpi(2, std::vector<std::string>{"-o", path(name + "_mpi.fits")} + args,
                                                       path("mpi.txt")),
                                             path("mpi.txt"));
    ASSERT_EQ(r.exit_code, 0) << r.err;
    expect_every_column_equal(path(name + "_single.fits"), path(name + "_mpi.fits"));
  }
}

// `stampede-mpi metadetect`: the ranks' shards joined are the single process's table, byte for byte
// (two ranks, and one); a rank killed then --resume gives it too.
TEST_F(MpiDriver, MetadetectOverTwoRanksWritesTheSingleProcessTable) {
  const auto sim = stampede::testing::finish(
      stampede::testing::spawn({"cells", "--out", path("cells"), "--cells", "12", "--layout", "random"}, path("sim.txt"), "sim"),
      path("sim.txt"));
  ASSERT_EQ(sim.exit_code, 0) << sim.err;
  std::vector<std::string> args;
  for (int k = 0; k < 12; ++k) {
    char name[32];
    std::snprintf(name, sizeof name, "/cell_%04d.fits", k);
    args.push_back(path("cells") + name);
  }
  args.insert(args.end(), {"--threads", "1", "--quiet"});
  const auto single = stampede::testing::finish(
      stampede::testing::spawn(std::vector<std::string>{"-o", path("single.fits"), "--package-output", path("single_pkg.fits")} + args,
                               path("single.txt"), "metadetect"),
      path("single.txt"));
  ASSERT_EQ(single.exit_code, 0) << single.err;
  const auto r = stampede::testing::finish(
      spawn_mpi(2, std::vector<std::string>{"-o", path("mpi.fits"), "--package-output", path("mpi_pkg.fits")} + args,
                path("mpi.txt"), "metadetect"),
      path("mpi.txt"));
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_EQ(read_bytes(path("single.fits")), read_bytes(path("mpi.fits")));
  // The package's layout written from the joined table: the same tables (the primary HDU, its
  // first 2880 bytes, names the table each was written from).
  const std::string a = read_bytes(path("single_pkg.fits")), b = read_bytes(path("mpi_pkg.fits"));
  ASSERT_GT(a.size(), 2880u * 6);
  EXPECT_EQ(a.substr(2880), b.substr(2880));
  EXPECT_FALSE(fs::exists(path("mpi_pkg.fits.partial")));
  EXPECT_FALSE(fs::exists(path("mpi.fits.part-0-of-2.fits")));
  // One rank (`mpirun -n 1`): its part, a whole table, is the output (merge refused it: no SHARD).
  const auto one = stampede::testing::finish(
      spawn_mpi(1, std::vector<std::string>{"-o", path("one.fits")} + args, path("one.txt"), "metadetect"), path("one.txt"));
  ASSERT_EQ(one.exit_code, 0) << one.err;
  EXPECT_EQ(read_bytes(path("single.fits")), read_bytes(path("one.fits")));
  EXPECT_FALSE(fs::exists(path("one.fits.part-0-of-1.fits")));
  // Killed when rank 1 has committed a cell: --resume finishes the job with the same table.
  const pid_t job = spawn_mpi(2, std::vector<std::string>{"-o", path("killed.fits")} + args, path("killed.txt"), "metadetect");
  const std::string checkpoint = path("killed.fits.part-1-of-2.fits.checkpoint");
  pid_t victim = -1;
  for (int i = 0; i < 3000 && victim < 0; ++i) {
    std::ifstream c(checkpoint);
    std::stringstream text;
    text << c.rdbuf();
    if (text.str().find("\nunits ") != std::string::npos && text.str().find("\nunits 0\n") == std::string::npos)
      victim = rank_pid(path("killed.fits"), 1);
    if (victim < 0) usleep(10000);
  }
  ASSERT_GT(victim, 0) << "rank 1 never committed a cell";
  kill(victim, SIGKILL);
  EXPECT_NE(stampede::testing::finish(job, path("killed.txt")).exit_code, 0);
  const auto resumed = stampede::testing::finish(
      spawn_mpi(2, std::vector<std::string>{"-o", path("killed.fits"), "--resume"} + args, path("resumed.txt"), "metadetect"),
      path("resumed.txt"));
  ASSERT_EQ(resumed.exit_code, 0) << resumed.err;
  EXPECT_EQ(read_bytes(path("single.fits")), read_bytes(path("killed.fits")));
}

}  // namespace

// What a single process refuses, `mpirun -n 2 stampede-mpi` refuses too, before any work and
// leaving the files as they were: an output that is an input (with --overwrite or --resume), an
// input named like the output's partial, another run's complete table or a file that is not a
// table under --resume. A resume of this run's complete table is skipped by both; a resume under
// another number of ranks than the job's parts were written by is refused, and a new job removes
// such leftovers. (Before: the MPI metadetect mode wrote over each of these files.)
TEST_F(MpiDriver, RefusesTheOutputsTheSingleProcessRefuses) {
  const auto sim = stampede::testing::finish(
      stampede::testing::spawn({"cells", "--out", path("cells"), "--cells", "3", "--seed", "3"}, path("sim.txt"), "sim"),
      path("sim.txt"));
  ASSERT_EQ(sim.exit_code, 0) << sim.err;
  const std::string cell0 = path("cells/cell_0000.fits"), cell1 = path("cells/cell_0001.fits");
  const std::vector<std::string> quiet = {"--threads", "1", "--quiet"};
  fs::copy_file(cell1, path("t.fits.partial"));
  fs::copy_file(kInput, path("grid.fits"));
  std::ofstream(path("notes.txt")) << "not a table\n";
  ASSERT_EQ(stampede::testing::finish(stampede::testing::spawn(std::vector<std::string>{cell0, cell1, "-o", path("other.fits"),
                                                                                        "--seed", "99"} + quiet,
                                                               path("other.txt"), "metadetect"),
                                      path("other.txt"))
                .exit_code,
            0);
  struct Case {
    std::string command;
    std::vector<std::string> args;
    std::string kept;  // a file that must be left as it was
    std::string expect;
  };
  const std::vector<Case> cases = {
      {"metadetect", {cell0, cell1, "-o", cell0, "--overwrite"}, cell0, "is the input"},
      {"metadetect", {cell0, cell1, "-o", cell1, "--resume"}, cell1, "is the input"},
      {"metadetect", {cell0, path("t.fits.partial"), "-o", path("t.fits")}, path("t.fits.partial"), "t.fits.partial"},
      {"metadetect", {cell0, cell1, "-o", path("other.fits"), "--resume"}, path("other.fits"), "written by another run"},
      {"metadetect", {cell0, cell1, "-o", path("notes.txt"), "--resume"}, path("notes.txt"), "notes.txt"},
      {"fit", {path("grid.fits"), "-o", path("grid.fits"), "--overwrite"}, path("grid.fits"), "grid.fits"},
      {"fit", {path("grid.fits"), "-o", path("notes.txt"), "--resume"}, path("notes.txt"), "notes.txt"},
  };
  for (const Case& c : cases) {
    const std::string before = read_bytes(c.kept);
    const std::vector<std::string> args = c.args + (c.command == "fit" ? kOptions : quiet);
    const auto single = stampede::testing::finish(stampede::testing::spawn(args, path("case.txt"), c.command), path("case.txt"));
    EXPECT_EQ(single.exit_code, 1) << c.expect << ": " << single.err;
    EXPECT_NE(single.err.find(c.expect), std::string::npos) << single.err;
    EXPECT_EQ(read_bytes(c.kept), before) << c.expect;
    const auto mpi = stampede::testing::finish(spawn_mpi(2, args, path("case_mpi.txt"), c.command), path("case_mpi.txt"));
    EXPECT_NE(mpi.exit_code, 0) << c.expect << ": " << mpi.err;
    EXPECT_NE(mpi.err.find(c.expect), std::string::npos) << mpi.err;
    EXPECT_EQ(read_bytes(c.kept), before) << c.expect << " (mpi)";
  }
  // This run's complete table: skipped by both.
  const std::vector<std::string> run = std::vector<std::string>{cell0, cell1, "-o", path("done.fits")} + quiet;
  ASSERT_EQ(stampede::testing::finish(spawn_mpi(2, run, path("done.txt"), "metadetect"), path("done.txt")).exit_code, 0);
  const std::string done = read_bytes(path("done.fits"));
  const auto skipped = stampede::testing::finish(
      spawn_mpi(2, run + std::vector<std::string>{"--resume"}, path("skip.txt"), "metadetect"), path("skip.txt"));
  EXPECT_EQ(skipped.exit_code, 0) << skipped.err;
  EXPECT_EQ(read_bytes(path("done.fits")), done);
  // Parts of a job of 3 ranks: a 2-rank resume is refused naming one; a new 2-rank job removes them.
  const std::string stale = path("job.fits.part-2-of-3.fits");
  std::ofstream(stale + ".partial") << "a part";
  std::ofstream(stale + ".checkpoint") << "a checkpoint";
  const std::vector<std::string> job = std::vector<std::string>{cell0, cell1, "-o", path("job.fits")} + quiet;
  const auto refused = stampede::testing::finish(
      spawn_mpi(2, job + std::vector<std::string>{"--resume"}, path("job1.txt"), "metadetect"), path("job1.txt"));
  EXPECT_NE(refused.exit_code, 0);
  EXPECT_NE(refused.err.find("job.fits.part-2-of-3.fits' is a part of a job of another number of ranks"), std::string::npos)
      << refused.err;
  EXPECT_TRUE(fs::exists(stale + ".checkpoint"));
  const auto fresh = stampede::testing::finish(spawn_mpi(2, job, path("job2.txt"), "metadetect"), path("job2.txt"));
  EXPECT_EQ(fresh.exit_code, 0) << fresh.err;
  EXPECT_EQ(read_bytes(path("job.fits")), done);
  EXPECT_FALSE(fs::exists(stale + ".checkpoint") || fs::exists(stale + ".partial"));
}
