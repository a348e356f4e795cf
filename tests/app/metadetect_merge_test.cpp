// Joining metadetection shards (app/metadetect_merge): three shards joined are the whole run's
// table byte for byte; a missing, repeated, unfinished or foreign shard is refused by name.
#include "app/metadetect_merge.hpp"

#include <gtest/gtest.h>
#include <tbb/global_control.h>

#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>
#include <vector>

#include "app/cell_simulation.hpp"
#include "app/metadetect_run.hpp"
#include "engine/common/error.hpp"
#include "support/metadetect_shards.hpp"
#include "support/scratch_dir.hpp"

namespace stampede::app {
namespace {

std::string bytes(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

std::string refusal(const MetadetectMergeOptions& o) {
  try {
    merge_metadetect_shards(o);
  } catch (const Error& e) {
    return e.what();
  }
  return "no error";
}

TEST(MetadetectMerge, ShardsJoinToTheWholeRunsTable) {
  testing::ScratchDir scratch("stampede_mdet_merge_");
  CellSimOptions so;
  so.layout = CellLayout::kRandom;
  CellOutputOptions out;
  out.cells = 5;
  {
    const tbb::global_control one(tbb::global_control::max_allowed_parallelism, 1);  // as metadetect_run_test's
    write_cell_simulation(so, out, scratch.path("sims"));
  }
  MetadetectRunOptions o;
  for (int k = 0; k < 5; ++k) o.inputs.push_back(scratch.path("sims/cell_000" + std::to_string(k) + ".fits"));
  o.output = scratch.path("whole.fits");
  run_metadetect(o);
  const std::vector<std::string> shards = testing::run_metadetect_shards(o, 3, scratch, "shard");
  const MetadetectMergeSummary s = merge_metadetect_shards({{shards[2], shards[0], shards[1]}, scratch.path("joined.fits")});
  EXPECT_EQ(s.shards, 3);
  EXPECT_EQ(s.cells, 5);
  EXPECT_EQ(bytes(scratch.path("whole.fits")), bytes(scratch.path("joined.fits")));

  const std::string missing = refusal({{shards[0], shards[2]}, scratch.path("m.fits")});
  EXPECT_NE(missing.find("shard 1 is missing"), std::string::npos) << missing;
  const std::string twice = refusal({{shards[0], shards[0], shards[1], shards[2]}, scratch.path("m.fits")});
  EXPECT_NE(twice.find("given twice"), std::string::npos) << twice;
  const std::string whole = refusal({{scratch.path("whole.fits")}, scratch.path("m.fits")});
  EXPECT_NE(whole.find("not a shard"), std::string::npos) << whole;
  o.shard = 1, o.shards = 3, o.output = scratch.path("other1.fits");
  o.metadetect.weight_fwhm = 1.5;  // another run
  run_metadetect(o);
  const std::string other = refusal({{shards[0], scratch.path("other1.fits"), shards[2]}, scratch.path("m.fits")});
  EXPECT_NE(other.find("other1.fits"), std::string::npos) << other;
  EXPECT_NE(other.find("WFWHM"), std::string::npos) << other;
  // An unfinished run's partial (here a shard's bytes under that name, as a failed finish leaves
  // them) or a shard with a checkpoint beside it is not a shard: refused, and left as it is.
  std::filesystem::copy_file(shards[1], scratch.path("s1.fits.partial"));
  const std::string partial = refusal({{shards[0], scratch.path("s1.fits.partial"), shards[2]}, scratch.path("m.fits")});
  EXPECT_NE(partial.find("s1.fits.partial: a run's unfinished partial file, not a shard"), std::string::npos) << partial;
  EXPECT_TRUE(std::filesystem::exists(scratch.path("s1.fits.partial")));
  std::ofstream(shards[1] + ".checkpoint") << "a run replacing it";
  const std::string replaced = refusal({{shards[0], shards[1], shards[2]}, scratch.path("m.fits")});
  EXPECT_NE(replaced.find(".checkpoint' is beside it"), std::string::npos) << replaced;
  EXPECT_FALSE(std::filesystem::exists(scratch.path("m.fits")));
}

}  // namespace
}  // namespace stampede::app
