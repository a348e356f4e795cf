// `stampede metadetect` end to end in a child process: a file-size limit (`ulimit -f`) met anywhere
// in the table's last blocks, the final close's included, never leaves a short table reported
// complete. Each limit either stops the run with its committed cells kept (and --resume then gives
// the uninterrupted table), or stops it with the incomplete table removed, or lets it finish whole.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>
#include <vector>

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

TEST(MetadetectCommand, AFileSizeLimitInTheLastBlocksNeverLeavesAShortTable) {
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
  ASSERT_GT(full.size(), 20000u);
  int kept = 0, removed = 0, whole = 0;
  // Every 1 KiB over the last 8 KiB of the table, and its exact size.
  for (long long limit = static_cast<long long>(full.size()) - 8192; limit <= static_cast<long long>(full.size());
       limit += limit + 1024 <= static_cast<long long>(full.size()) ? 1024 : std::max(1LL, static_cast<long long>(full.size()) - limit)) {
    std::string name = std::to_string(limit);  // (not "t" + ...: GCC 12's -Wrestrict false positive)
    name.append(".fits");
    const std::string out = dir.path(name);
    const testing::RunResult r = run(args(out, false), out + ".err", "metadetect", limit);
    if (r.exit_code == 0) {
      EXPECT_EQ(bytes_of(out), full) << "limit " << limit << ": a table reported complete must be whole";
      ++whole;
    } else if (fs::exists(out + ".partial")) {
      EXPECT_EQ(r.exit_code, 1) << r.err;
      EXPECT_TRUE(fs::exists(out + ".checkpoint")) << limit;
      EXPECT_NE(r.err.find("--resume"), std::string::npos) << r.err;
      const testing::RunResult resumed = run(args(out, true), out + ".resume.err", "metadetect");
      ASSERT_EQ(resumed.exit_code, 0) << "limit " << limit << ": " << resumed.err;
      EXPECT_EQ(bytes_of(out), full) << "limit " << limit << ": the resumed table";
      ++kept;
    } else {
      EXPECT_EQ(r.exit_code, 1) << r.err;
      EXPECT_FALSE(fs::exists(out) || fs::exists(out + ".checkpoint")) << limit;
      EXPECT_NE(r.err.find("the table is incomplete and was removed"), std::string::npos) << r.err;
      EXPECT_NE(r.err.find("file-size limit"), std::string::npos) << r.err;
      ++removed;
    }
    if (limit == static_cast<long long>(full.size())) break;
  }
  std::printf("limits over the last 8 KiB: %d kept for resume, %d removed, %d whole\n", kept, removed, whole);
  EXPECT_GT(removed, 0);  // the final close's blocks: where a short table used to be named complete
  EXPECT_GT(whole, 0);
}

}  // namespace
}  // namespace stampede
