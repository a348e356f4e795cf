// A worker's recipe (app/worker_recipe): what a run tells an MPI worker gives back the run's own
// measurer — a metadetection's every option, band roles and SEP pixel stack; a fit's effective
// configuration. A line a kind does not read, or a kind no run has, is refused naming it.
#include "app/worker_recipe.hpp"

#include <gtest/gtest.h>

#include <string>

#include "app/metadetect_option_keys.hpp"
#include "io/config_error.hpp"

namespace stampede::app {
namespace {

TEST(WorkerRecipe, AMetadetectionsOptionsReadBackFromItsRecipe) {
  MetadetectOptions changed;
  changed.cell_size = 201, changed.cell_buffer = 40, changed.step = 0.02, changed.psf_dilation = 1.25;
  changed.reconvolution = ReconvolutionRule::kMoffat, changed.fixnoise = false, changed.double_images = true;
  changed.symmetrise_mask = false, changed.mfrac_fwhm = 1.7, changed.noise_plane = false, changed.seed = 77;
  changed.measurement = MetadetectMeasurement::kPgauss, changed.weight_fwhm = 1.9, changed.recentre = true;
  changed.detection.threshold = 1.1, changed.detection.clean_param = 1.5, changed.stamp.padding = 1.0;
  changed.detect_bands = 0b110, changed.shear_bands = 0b011;
  const WorkerRecipe recipe = metadetect_worker_recipe(changed, 123456, 3);
  EXPECT_EQ(recipe.kind, "metadetect");
  EXPECT_EQ(recipe.batch_size, 3);
  long long pixel_stack = 0;
  const MetadetectOptions read = metadetect_recipe_options(recipe, &pixel_stack);
  EXPECT_EQ(metadetect_header_keys(read), metadetect_header_keys(changed));
  EXPECT_NE(metadetect_header_keys(read), metadetect_header_keys(MetadetectOptions()));
  EXPECT_EQ(read.detect_bands, changed.detect_bands);
  EXPECT_EQ(read.shear_bands, changed.shear_bands);
  EXPECT_EQ(pixel_stack, 123456);
  EXPECT_NE(worker_measurers(recipe)(), nullptr);
}

TEST(WorkerRecipe, AFitsConfigurationIsItsEffectiveOptions) {
  RunConfig config;
  set_option(config, "stamp_size", "39");
  set_option(config, "psf_fwhm", "3.1");
  set_option(config, "batch_size", "7");
  const WorkerRecipe recipe = fit_worker_recipe(config, {"g.fits", "r.fits"}, {"g", "r"});
  EXPECT_EQ(recipe.kind, "fit");
  EXPECT_EQ(recipe.batch_size, 7);
  RunConfig read;
  int tiles = 0, bands = 0;
  for (const auto& [key, value] : recipe.lines) {
    if (key == "mpi_meds") {
      ++tiles;
    } else if (key == "mpi_band") {
      ++bands;
    } else {
      set_option(read, key, value);
    }
  }
  EXPECT_EQ(tiles, 2);
  EXPECT_EQ(bands, 2);
  EXPECT_EQ(effective_options(read), effective_options(config));
}

TEST(WorkerRecipe, UnknownKindsAndLinesAreRefusedByName) {
  WorkerRecipe recipe{"sort", {}, 1};
  try {
    worker_measurers(recipe);
    FAIL() << "a kind no run has was accepted";
  } catch (const io::ConfigError& e) {
    EXPECT_NE(std::string(e.what()).find("'sort'"), std::string::npos) << e.what();
  }
  recipe = metadetect_worker_recipe(MetadetectOptions(), 1000, 2);
  recipe.lines.emplace_back("NOSUCHKY", "1");
  long long pixel_stack = 0;
  try {
    metadetect_recipe_options(recipe, &pixel_stack);
    FAIL() << "a line no option records was accepted";
  } catch (const io::ConfigError& e) {
    EXPECT_NE(std::string(e.what()).find("'NOSUCHKY'"), std::string::npos) << e.what();
  }
  recipe = metadetect_worker_recipe(MetadetectOptions(), 1000, 2);
  recipe.lines.emplace_back("CELLSIZE", "3");  // the last line of a key holds; below the least
  try {
    metadetect_recipe_options(recipe, &pixel_stack);
    FAIL() << "invalid options were accepted";
  } catch (const io::ConfigError& e) {
    EXPECT_NE(std::string(e.what()).find("cell_size"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace stampede::app
