// `stampede metadetect` end to end in a child process: a file-size limit (`ulimit -f`) of any size
// up to the table's, met anywhere (a commit, the final close), never leaves a short table reported
// complete, and --resume then gives the uninterrupted table byte for byte; where nothing was
// committed the resume starts the run.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>
#include <vector>

#include "io/fits_file.hpp"
#include "support/command_runner.hpp"
#include "support/scratch_dir.hpp"

namespace stampede {
namespace {

namespace fs = std::filesystem;

std::string bytes_of(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
}

testing::RunResult run(const std::vector<std::string>& args, const std::string& err, const std::string& command,
                       long long limit = -1) {
  return testing::finish(testing::spawn(args, err, command, "/dev/null", limit), err);
}

TEST(MetadetectCommand, EveryFileSizeLimitResumesToTheUninterruptedTable) {
  testing::ScratchDir dir("stampede_mdet_limit_");
  const std::string cells = dir.path("cells");
  ASSERT_EQ(run({"cells", "--cells", "3", "--seed", "5", "--out", cells}, dir.path("sim.txt"), "sim").exit_code, 0);
  std::vector<std::string> inputs;
  for (int k = 0; k < 3; ++k) inputs.push_back(cells + "/cell_000" + std::to_string(k) + ".fits");
  auto args = [&](const std::string& out, bool resume) {
    std::vector<std::string> a = inputs;
    a.insert(a.end(), {std::string("-o"), out, std::string("--quiet"), std::string("--threads"), std::string("1")});
    if (resume) a.push_back("--resume");
    return a;
  };
  ASSERT_EQ(run(args(dir.path("full.fits"), false), dir.path("full.txt"), "metadetect").exit_code, 0);
  const std::string full = bytes_of(dir.path("full.fits"));
  const auto size = static_cast<long long>(full.size());
  ASSERT_GT(size, 20000);
  int resumed = 0, started = 0, whole = 0;
  // Every 2 KiB from 1 KiB, then the table's last bytes.
  std::vector<long long> limits;
  for (long long limit = 1024; limit < size; limit += 2048) limits.push_back(limit);
  for (long long back : {1024LL, 512LL, 1LL, 0LL}) limits.push_back(size - back);
  for (const long long limit : limits) {
    std::string name = std::to_string(limit);  // (not "t" + ...: GCC 12's -Wrestrict false positive)
    name.append(".fits");
    const std::string out = dir.path(name);
    const testing::RunResult r = run(args(out, false), out + ".err", "metadetect", limit);
    if (r.exit_code == 0) {
      EXPECT_EQ(bytes_of(out), full) << "limit " << limit << ": a table reported complete must be whole";
      ++whole;
      continue;
    }
    EXPECT_EQ(r.exit_code, 1) << r.err;
    EXPECT_FALSE(fs::exists(out)) << limit;
    EXPECT_NE(r.err.find("file-size limit"), std::string::npos) << r.err;
    const bool kept = fs::exists(out + ".checkpoint");
    if (kept) {
      EXPECT_NE(r.err.find("committed before it are kept"), std::string::npos) << r.err;
    }
    const testing::RunResult again = run(args(out, true), out + ".resume.err", "metadetect");
    ASSERT_EQ(again.exit_code, 0) << "limit " << limit << ": " << again.err;
    EXPECT_EQ(bytes_of(out), full) << "limit " << limit << ": the resumed table";
    EXPECT_EQ(again.err.find("nothing to resume") == std::string::npos, kept) << again.err;
    ++(kept ? resumed : started);
  }
  std::printf("%zu limits: %d resumed, %d started by --resume, %d whole\n", limits.size(), resumed, started, whole);
  EXPECT_GT(resumed, 10);
  EXPECT_GT(started, 0);
  EXPECT_GT(whole, 0);
}

// The options' rules in the command line's words: the core names fields (cell_size), the command
// speaks flags (--cell-size); a value that does not read names the flag and the text.
TEST(MetadetectCommand, BadOptionsAreRefusedInTheCommandLinesWords) {
  testing::ScratchDir dir("stampede_mdet_options_");
  const testing::RunResult size = run({"in.fits", "-o", dir.path("o.fits"), "--cell-size", "3"}, dir.path("a.txt"), "metadetect");
  EXPECT_NE(size.exit_code, 0);
  EXPECT_NE(size.err.find("--cell-size = 3: must be in [16, 4096] pixels"), std::string::npos) << size.err;
  const testing::RunResult box = run({"in.fits", "-o", dir.path("o.fits"), "--box-max", "31"}, dir.path("b.txt"), "metadetect");
  EXPECT_NE(box.err.find("--box-max = 31: must be odd, >= --box-min (33) and <= 4095"), std::string::npos) << box.err;
  const testing::RunResult m = run({"in.fits", "-o", dir.path("o.fits"), "--measurement", "ksigma"}, dir.path("c.txt"), "metadetect");
  EXPECT_NE(m.err.find("option --measurement 'ksigma': must be wmom, pgauss, gauss, exp or bd"), std::string::npos) << m.err;
  const testing::RunResult n = run({"in.fits", "-o", dir.path("o.fits"), "--step", "1e"}, dir.path("d.txt"), "metadetect");
  EXPECT_NE(n.err.find("option --step '1e': "), std::string::npos) << n.err;
  const testing::RunResult g = run({"in.fits", "-o", dir.path("o.fits"), "--geometry", "hsc"}, dir.path("e.txt"), "metadetect");
  EXPECT_NE(g.err.find("option --geometry 'hsc': must be des-y6 or rubin"), std::string::npos) << g.err;
  const testing::RunResult both =
      run({"in.fits", "-o", dir.path("o.fits"), "--geometry", "rubin", "--cell-buffer", "34"}, dir.path("f.txt"), "metadetect");
  EXPECT_NE(both.err.find("--geometry sets --cell-size 250 --cell-buffer 50: give one or the other"), std::string::npos)
      << both.err;
  EXPECT_FALSE(fs::exists(dir.path("o.fits")));
}

// --geometry lays the survey's cells out: Rubin's 250 px cells with 50 px borders, as if given as
// --cell-size and --cell-buffer (the header records them so).
TEST(MetadetectCommand, GeometryPresetsSetTheCellSizeAndBuffer) {
  testing::ScratchDir dir("stampede_mdet_geometry_");
  const testing::RunResult sim =
      run({"cells", "--out", dir.path("sims"), "--size", "300", "--snr", "1e4"}, dir.path("s.txt"), "sim");
  ASSERT_EQ(sim.exit_code, 0) << sim.err;
  const testing::RunResult r = run({dir.path("sims/cell_0000.fits"), "-o", dir.path("o.fits"), "--geometry", "rubin",
                                    "--quiet"}, dir.path("r.txt"), "metadetect");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  io::FitsFile f = io::FitsFile::open_read(dir.path("o.fits"));
  f.move_to("METADETECT");
  EXPECT_EQ(f.read_key_long("CELLSIZE").value_or(0), 250);
  EXPECT_EQ(f.read_key_long("CELLBUF").value_or(0), 50);
}

}  // namespace
}  // namespace stampede
