// The metrics of metadetection catalogues (app/metadetect_metrics) check a shear pair by what its
// tables record, not by their names: the same table or a copy on both sides, a pair swapped, a
// table not turned given as turned, tables of other measurements or weights are refused naming
// what differs; the true shear is the one the inputs record (a --shear that contradicts it is
// refused); cuts that keep no row are an error naming the cuts; a pgauss table's default T_ratio
// cut is its own.
#include "app/metadetect_metrics.hpp"

#include <gtest/gtest.h>
#include <tbb/global_control.h>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <stdexcept>
#include <string>
#include <vector>

#include "app/cell_simulation.hpp"
#include "app/metadetect_run.hpp"
#include "engine/sim/cell_sim.hpp"
#include "support/scratch_dir.hpp"

namespace stampede::app {
namespace {

class MetadetectMetricsTest : public ::testing::Test {
 protected:
  // Two cells of the reference grid (nearly noise-free) under +g and -g, and turned by 90 degrees.
  static void SetUpTestSuite() {
    dir_ = new testing::ScratchDir("stampede_mdet_metrics_");
    const tbb::global_control one(tbb::global_control::max_allowed_parallelism, 1);
    CellSimOptions so;
    so.snr = 1e4;
    so.grid = 4;
    CellOutputOptions out;
    out.cells = 2;
    out.pair = true;
    write_cell_simulation(so, out, dir_->path("sims"));
    so.rotate = true;
    write_cell_simulation(so, out, dir_->path("turned"));
    so.rotate = false;
    so.seed += 1;
    write_cell_simulation(so, out, dir_->path("other_scene"));
  }
  static void TearDownTestSuite() { delete dir_; }

  static std::vector<std::string> cells(const std::string& sub) {
    std::vector<std::string> paths;
    for (int k = 0; k < 2; ++k) {
      char name[32];
      std::snprintf(name, sizeof name, "/cell_%04d.fits", k);
      paths.push_back(dir_->path(sub) + name);
    }
    return paths;
  }
  // The table of the cells under `sub`, measured with `change` applied to the options.
  static std::string table(const std::string& sub, const std::string& name,
                           void (*change)(MetadetectOptions&) = nullptr) {
    MetadetectRunOptions o;
    o.inputs = cells(sub);
    o.output = dir_->path(name);
    o.threads = 1;
    if (change) change(o.metadetect);
    if (!std::filesystem::exists(o.output)) run_metadetect(o);
    return o.output;
  }
  static std::string error_of(const MetadetectMetricsOptions& o) {
    try {
      metadetect_metrics(o);
    } catch (const std::exception& e) {
      return e.what();
    }
    return "no error";
  }
  static testing::ScratchDir* dir_;
};
testing::ScratchDir* MetadetectMetricsTest::dir_ = nullptr;

TEST_F(MetadetectMetricsTest, APairIsMeasuredWithTheShearItsInputsRecord) {
  MetadetectMetricsOptions o;
  o.table = table("sims", "plus.fits");
  o.minus = table("sims/minus", "minus.fits");
  const MetadetectMetrics r = metadetect_metrics(o);
  ASSERT_TRUE(r.has_bias);
  EXPECT_EQ(r.true_shear[0], 0.02);
  EXPECT_EQ(r.true_shear[1], 0.0);
  EXPECT_LT(std::abs(r.bias.m1), 0.05) << r.bias.m1;
  // Swapped, the table's own inputs say its shear is -0.02: the same m, not -2.
  MetadetectMetricsOptions swapped;
  swapped.table = o.minus, swapped.minus = o.table;
  const MetadetectMetrics s = metadetect_metrics(swapped);
  EXPECT_EQ(s.true_shear[0], -0.02);
  EXPECT_NEAR(s.bias.m1, r.bias.m1, 1e-9);
  // ... and a --shear that contradicts what they record is refused.
  swapped.shear = std::array<double, 2>{0.02, 0};
  EXPECT_NE(error_of(swapped).find("record the shear (-0.02, 0)"), std::string::npos) << error_of(swapped);
}

TEST_F(MetadetectMetricsTest, TheSameTableOrACopyIsNoPair) {
  MetadetectMetricsOptions o;
  o.table = table("sims", "plus.fits");
  o.minus = o.table;
  EXPECT_NE(error_of(o).find("measured the same input files"), std::string::npos) << error_of(o);
  std::filesystem::copy_file(o.table, dir_->path("copy.fits"), std::filesystem::copy_options::overwrite_existing);
  o.minus = dir_->path("copy.fits");
  EXPECT_NE(error_of(o).find("measured the same input files"), std::string::npos) << error_of(o);
}

TEST_F(MetadetectMetricsTest, TablesOfOtherMeasurementsOrWeightsAreNoPair) {
  MetadetectMetricsOptions o;
  o.table = table("sims", "plus.fits");
  o.minus = table("sims/minus", "minus_pgauss.fits", [](MetadetectOptions& m) {
    m.measurement = MetadetectMeasurement::kPgauss;
    m.weight_fwhm = 1.2;  // wmom's: the measurement alone differs
  });
  EXPECT_NE(error_of(o).find("MEASURE = 'pgauss' there, 'wmom' here"), std::string::npos) << error_of(o);
  o.minus = table("sims/minus", "minus_wide.fits", [](MetadetectOptions& m) { m.weight_fwhm = 2.0; });
  EXPECT_NE(error_of(o).find("are not measured alike: WFWHM"), std::string::npos) << error_of(o);
}

TEST_F(MetadetectMetricsTest, ATurnedSceneMustBeTurnedAndOfTheSameScene) {
  MetadetectMetricsOptions o;
  o.table = table("sims", "plus.fits");
  o.minus = table("sims/minus", "minus.fits");
  o.rotated = table("turned", "turned.fits");
  o.rotated_minus = table("turned/minus", "turned_minus.fits");
  const MetadetectMetrics r = metadetect_metrics(o);
  EXPECT_TRUE(r.has_bias);
  // Another unturned scene given as the turned one; the turned pair swapped.
  MetadetectMetricsOptions not_turned = o;
  not_turned.rotated = table("other_scene", "other.fits");
  not_turned.rotated_minus = table("other_scene/minus", "other_minus.fits");
  EXPECT_NE(error_of(not_turned).find("the scene is not turned between them"), std::string::npos) << error_of(not_turned);
  MetadetectMetricsOptions swapped = o;
  std::swap(swapped.rotated, swapped.rotated_minus);
  EXPECT_NE(error_of(swapped).find("not the same one"), std::string::npos) << error_of(swapped);
  MetadetectMetricsOptions other_scene = o;
  other_scene.minus = table("other_scene/minus", "other_minus.fits");
  other_scene.rotated.clear(), other_scene.rotated_minus.clear();
  EXPECT_NE(error_of(other_scene).find("are of other scenes (seeds"), std::string::npos) << error_of(other_scene);
}

TEST_F(MetadetectMetricsTest, CutsThatKeepNoRowAreAnErrorAndPgaussHasItsOwnDefault) {
  MetadetectMetricsOptions o;
  o.table = table("sims", "plus.fits");
  o.cut_snr = 1e12;
  EXPECT_NE(error_of(o).find("none of its"), std::string::npos) << error_of(o);
  EXPECT_NE(error_of(o).find("pass the cuts (flags 0, snr > 1e+12, T_ratio > 1.2, mfrac <= 0.1)"), std::string::npos) << error_of(o);
  MetadetectMetricsOptions p;
  p.table = table("sims", "plus_pgauss.fits", [](MetadetectOptions& m) { m.measurement = MetadetectMeasurement::kPgauss; });
  const MetadetectMetrics r = metadetect_metrics(p);
  EXPECT_EQ(r.cuts.min_t_ratio, 0.5);
  EXPECT_GT(r.shear.kept_noshear, 0);
  EXPECT_TRUE(std::isfinite(r.shear.r11));
}

}  // namespace
}  // namespace stampede::app
