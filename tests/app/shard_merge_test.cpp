// app/shard_merge with FitRun's shards: N shards of a grid joined are the single run's table (every
// column but time_us, bit for bit, the run's header keys included), whatever N and the order the
// shards are given in; missing, duplicated, foreign and non-shard tables are refused naming the
// file. (A killed shard resumed as itself: tests/tools/fit_command_test.cpp.) With metadetect's
// shards, the same merge gives the whole run's table byte for byte.
#include "app/shard_merge.hpp"

#include <fitsio.h>
#include <gtest/gtest.h>

#include <cstring>
#include <iterator>
#include <fstream>
#include <tbb/global_control.h>
#include <filesystem>
#include <string>
#include <vector>

#include "app/cell_simulation.hpp"
#include "app/metadetect_run.hpp"
#include "support/metadetect_shards.hpp"
#include "engine/common/error.hpp"
#include "app/fit_run.hpp"
#include "io/catalog_reader.hpp"
#include "io/catalog_writer.hpp"
#include "io/durable_file.hpp"
#include "io/fits_file.hpp"
#include "support/error_assertions.hpp"
#include "support/fit_output.hpp"
#include "support/scratch_dir.hpp"

namespace {

using namespace stampede;
using stampede::testing::expect_tables_equal;
using stampede::testing::Contains;
using stampede::testing::error_of;

constexpr int kNx = 7, kNy = 1, kStamp = 39, kCount = kNx * kNy;

class ShardMergeTest : public ::testing::Test {
 protected:
  void SetUp() override {
    io::FitsFile in = io::FitsFile::open_read(std::string(STAMPEDE_DATA_DIR) + "/galsim-great08-mini/snr40/set_0.fits");
    const long width = in.image_shape().nx;
    const std::vector<double> all = in.read_image();
    std::vector<double> part;
    for (long y = 0; y < kNy * kStamp; ++y)
      part.insert(part.end(), all.begin() + y * width, all.begin() + y * width + kNx * kStamp);
    io::FitsFile out = io::FitsFile::create(input, true);
    out.write_image(kNx * kStamp, kNy * kStamp, part);
    out.write_key("STAMPSZ", kStamp, "stamp size");
  }
  app::FitRunOptions options(const std::string& output, int shard, int shards) const {
    app::FitRunOptions o;
    o.input = input;
    o.output = output;
    o.threads = 2;
    o.shard = shard;
    o.shards = shards;
    for (const char* s : {"psf_beta=3", "psf_fwhm=2.85", "psf_e2=0.05", "noise_sigma=1", "renderer=exact",
                          "minimizer_max_iterations=20", "batch_size=2"})
      app::apply_set(o.config, s);
    return o;
  }
  std::vector<std::string> run_shards(int n, const std::string& prefix) const {
    std::vector<std::string> paths;
    for (int i = 0; i < n; ++i) {
      paths.push_back(scratch.path(prefix + std::to_string(i) + ".fits"));
      app::FitRun(options(paths.back(), i, n)).run();
    }
    return paths;
  }
  stampede::testing::ScratchDir scratch{"stampede_shard_merge_"};
  std::string input = scratch.path("grid.fits");
};

TEST_F(ShardMergeTest, ShardsJoinedAreTheSingleRunsTable) {
  const std::string whole = scratch.path("whole.fits");
  app::FitRun(options(whole, 0, 1)).run();
  for (int n : {2, 3, 7}) {
    std::vector<std::string> shards = run_shards(n, std::string(1, 'n').append(std::to_string(n)).append("_"));  // not "n" + ...: GCC 12 -Wrestrict false positive
    std::swap(shards.front(), shards.back());  // any order
    app::ShardMergeOptions m;
    m.shards = shards;
    m.output = scratch.path("merged" + std::to_string(n) + ".fits");
    const app::ShardMergeSummary s = app::merge_shards(m);
    EXPECT_EQ(s.shards, n);
    EXPECT_EQ(s.rows, kCount);
    expect_tables_equal(m.output, whole);
    io::FitsFile f = io::FitsFile::open_read(m.output);
    f.move_to("RESULTS");
    io::FitsFile g = io::FitsFile::open_read(whole);
    g.move_to("RESULTS");
    for (const char* key : {"renderer", "psf_e2", "minimizer_max_iterations", "INPUT"})
      EXPECT_EQ(f.key_string(key), g.key_string(key)) << key;
    EXPECT_EQ(f.read_key_string(app::kShardKey), std::nullopt);
  }
  // A shard holds its range with whole-input ids: 7 objects in 3 shards are 2, 2, 3.
  io::CatalogReader r = io::CatalogReader::open(scratch.path("n3_1.fits"));
  EXPECT_EQ(r.column(io::ResultField::kId), (std::vector<double>{2, 3}));
}

TEST_F(ShardMergeTest, MissingDuplicatedForeignAndNonShardTablesAreRefused) {
  const std::vector<std::string> shards = run_shards(3, "s");
  app::ShardMergeOptions m;
  m.output = scratch.path("merged.fits");
  m.shards = {shards[0], shards[2]};
  EXPECT_TRUE(Contains(error_of<io::CatalogError>([&] { app::merge_shards(m); }), "shard 1/3 is missing (2 of 3 given)"));
  m.shards = {shards[0], shards[1], shards[1], shards[2]};
  EXPECT_TRUE(Contains(error_of<io::CatalogError>([&] { app::merge_shards(m); }), "s1.fits are both shard 1/3"));

  app::FitRunOptions other = options(scratch.path("other1.fits"), 1, 3);
  app::apply_set(other.config, "psf_e2=0.04");
  app::FitRun(other).run();
  m.shards = {shards[0], other.output, shards[2]};
  EXPECT_TRUE(Contains(error_of<io::CatalogError>([&] { app::merge_shards(m); }),
                       "other1.fits is from another run than " + shards[0] + ": psf_e2 = '0.04' there, '0.05' here"));

  app::FitRun(options(scratch.path("four1.fits"), 1, 4)).run();
  m.shards = {shards[0], scratch.path("four1.fits")};
  EXPECT_TRUE(Contains(error_of<io::CatalogError>([&] { app::merge_shards(m); }), "four1.fits is shard 1/4 of 7 objects"));

  const std::string whole = scratch.path("whole.fits");
  app::FitRun(options(whole, 0, 1)).run();
  m.shards = {whole};
  EXPECT_TRUE(Contains(error_of<io::CatalogError>([&] { app::merge_shards(m); }),
                       "whole.fits: no SHARD key: not the table of a `stampede fit --shard i/N` run"));
  EXPECT_FALSE(std::filesystem::exists(m.output));
  EXPECT_FALSE(std::filesystem::exists(m.output + ".partial"));

  // An unfinished run's partial given as a shard is refused and left as it is.
  std::filesystem::copy_file(shards[1], shards[1] + ".partial");
  m.shards = {shards[0], shards[1] + ".partial", shards[2]};
  EXPECT_TRUE(Contains(error_of<io::CatalogError>([&] { app::merge_shards(m); }), "a run's unfinished partial file, not a shard"));
  EXPECT_TRUE(std::filesystem::exists(shards[1] + ".partial"));

  m.shards = shards;
  app::merge_shards(m);
  EXPECT_TRUE(Contains(error_of<io::FileError>([&] { app::merge_shards(m); }), "merged.fits' exists"));
  m.overwrite = true;
  EXPECT_EQ(app::merge_shards(m).rows, kCount);
}

TEST_F(ShardMergeTest, AShardOutsideItsCountIsAConfigError) {
  EXPECT_TRUE(Contains(error_of<io::ConfigError>([&] { app::FitRun(options(scratch.path("x.fits"), 3, 3)).run(); }),
                       "--shard 3/3: must be i/N with 0 <= i < N"));
  EXPECT_TRUE(Contains(error_of<io::ConfigError>([&] { app::FitRun(options(scratch.path("x.fits"), 0, 0)).run(); }),
                       "--shard 0/0"));
}

}  // namespace

namespace stampede::app {
namespace {

std::string bytes(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

ShardMergeOptions merge(std::vector<std::string> shards, const std::string& output) {
  ShardMergeOptions o;
  o.shards = std::move(shards);
  o.output = output;
  return o;
}

std::string refusal(const ShardMergeOptions& o) {
  try {
    merge_shards(o);
  } catch (const Error& e) {
    return e.what();
  }
  return "no error";
}

TEST(ShardMerge, MetadetectShardsJoinToTheWholeRunsTableByteForByte) {
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
  const ShardMergeSummary s = merge_shards(merge({shards[2], shards[0], shards[1]}, scratch.path("joined.fits")));
  EXPECT_TRUE(s.metadetect);
  EXPECT_EQ(s.shards, 3);
  EXPECT_EQ(s.units, 5);
  EXPECT_EQ(bytes(scratch.path("whole.fits")), bytes(scratch.path("joined.fits")));

  const std::string missing = refusal(merge({shards[0], shards[2]}, scratch.path("m.fits")));
  EXPECT_NE(missing.find("shard 1/3 is missing"), std::string::npos) << missing;
  const std::string twice = refusal(merge({shards[0], shards[0], shards[1], shards[2]}, scratch.path("m.fits")));
  EXPECT_NE(twice.find("a shard given twice"), std::string::npos) << twice;
  const std::string whole = refusal(merge({scratch.path("whole.fits")}, scratch.path("m.fits")));
  EXPECT_NE(whole.find("not the table of a `stampede metadetect --shard i/N` run"), std::string::npos) << whole;
  o.shard = 1, o.shards = 3, o.output = scratch.path("other1.fits");
  o.metadetect.weight_fwhm = 1.5;  // another run
  run_metadetect(o);
  const std::string other = refusal(merge({shards[0], scratch.path("other1.fits"), shards[2]}, scratch.path("m.fits")));
  EXPECT_NE(other.find("other1.fits"), std::string::npos) << other;
  EXPECT_NE(other.find("WFWHM"), std::string::npos) << other;
  // An unfinished run's partial (here a shard's bytes under that name, as a failed finish leaves
  // them) or a shard with a checkpoint beside it is not a shard: refused, and left as it is.
  std::filesystem::copy_file(shards[1], scratch.path("s1.fits.partial"));
  const std::string partial = refusal(merge({shards[0], scratch.path("s1.fits.partial"), shards[2]}, scratch.path("m.fits")));
  EXPECT_NE(partial.find("s1.fits.partial: a run's unfinished partial file, not a shard"), std::string::npos) << partial;
  EXPECT_TRUE(std::filesystem::exists(scratch.path("s1.fits.partial")));
  std::ofstream(shards[1] + ".checkpoint") << "a run replacing it";
  const std::string replaced = refusal(merge({shards[0], shards[1], shards[2]}, scratch.path("m.fits")));
  EXPECT_NE(replaced.find(".checkpoint' is beside it"), std::string::npos) << replaced;
  std::filesystem::remove(shards[1] + ".checkpoint");
  // A shard that lost a row since its run wrote it (NROWSW records what it wrote) is refused.
  std::filesystem::copy_file(shards[2], scratch.path("lost2.fits"));
  {
    fitsfile* f = nullptr;
    int status = 0;
    fits_open_file(&f, scratch.path("lost2.fits").c_str(), READWRITE, &status);
    fits_movnam_hdu(f, BINARY_TBL, const_cast<char*>("METADETECT"), 0, &status);
    fits_delete_rows(f, 1, 1, &status);
    fits_close_file(f, &status);
    ASSERT_EQ(status, 0);
  }
  const std::string lost = refusal(merge({shards[0], shards[1], scratch.path("lost2.fits")}, scratch.path("m.fits")));
  EXPECT_NE(lost.find("lost2.fits: holds "), std::string::npos) << lost;
  EXPECT_NE(lost.find("(NROWSW): rows were lost or added since"), std::string::npos) << lost;
  EXPECT_FALSE(std::filesystem::exists(scratch.path("m.fits")));
}

}  // namespace
}  // namespace stampede::app
