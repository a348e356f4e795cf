// `mpirun -n 2 stampede-mpi fit`: the one table equals a single process's (every column but
// time_us); a job whose worker rank is killed mid-run resumes to the same table; a rank-0 error is
// an error of the job (no hang). Run as root in CI: OMPI_ALLOW_RUN_AS_ROOT is set for mpirun.
#include <gtest/gtest.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "io/catalog_reader.hpp"
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

// `mpirun -n RANKS stampede-mpi fit ARGS...`, stderr to err_path.
pid_t spawn_mpi(int ranks, std::vector<std::string> args, const std::string& err_path) {
  const pid_t pid = fork();
  if (pid == 0) {
    FILE* e = std::fopen(err_path.c_str(), "w");
    if (e) dup2(fileno(e), 2);
    setenv("OMPI_ALLOW_RUN_AS_ROOT", "1", 1);
    setenv("OMPI_ALLOW_RUN_AS_ROOT_CONFIRM", "1", 1);
    std::vector<std::string> all = {STAMPEDE_MPIEXEC, "-n", std::to_string(ranks), "--oversubscribe",
                                    STAMPEDE_MPI_BINARY, "fit"};
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
}

TEST_F(MpiDriver, AKilledWorkerRankThenResumeGivesTheSameTable) {
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
  const auto resumed = stampede::testing::finish(spawn_mpi(2, (std::vector<std::string>{kInput, "-o", out, "--resume"} + kOptions),
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
  // --resume skips complete outputs.
  r = stampede::testing::finish(
      spawn_mpi(2, (std::vector<std::string>{"--input-list", path("tiles.txt"), "-o", path("out"), "--resume"} + std::vector<std::string>{"--threads", "1"}),
                path("again.txt")),
      path("again.txt"));
  EXPECT_EQ(r.exit_code, 0) << r.err;
  EXPECT_NE(r.err.find("set_1_fit.fits is complete, skipped"), std::string::npos) << r.err;
}

TEST_F(MpiDriver, AnErrorOnRankZeroEndsTheJob) {
  const auto r = stampede::testing::finish(
      spawn_mpi(2, (std::vector<std::string>{path("missing.fits"), "-o", path("x.fits")} + kOptions), path("err.txt")), path("err.txt"));
  EXPECT_NE(r.exit_code, 0);
  EXPECT_NE(r.err.find("missing.fits"), std::string::npos) << r.err;
}

// The workers fit the pixels they are sent and a survey batch carries only row numbers: a MEDS tile
// is refused by name (and nothing is written), never fitted wrong on the other ranks.
TEST_F(MpiDriver, AMedsTileIsRefusedNotFittedWrong) {
  const auto r = stampede::testing::finish(
      spawn_mpi(2, {"--meds", std::string(STAMPEDE_DATA_DIR) + "/meds-sample/meds.fits", "-o", path("m.fits"), "--threads",
                    "1", "--quiet"},
                path("err.txt")),
      path("err.txt"));
  EXPECT_NE(r.exit_code, 0);
  EXPECT_NE(r.err.find("--meds with stampede-mpi"), std::string::npos) << r.err;
  EXPECT_FALSE(fs::exists(path("m.fits")));
  EXPECT_FALSE(fs::exists(path("m.fits.partial")));
}

}  // namespace
