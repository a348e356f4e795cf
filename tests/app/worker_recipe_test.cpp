// A worker's recipe (app/worker_recipe): what a fit run tells an MPI worker gives back the run's
// effective configuration, tiles and bands; a line no option is, or a kind no run has, is refused
// naming it.
#include "app/worker_recipe.hpp"

#include <gtest/gtest.h>

#include <string>

#include "io/config_error.hpp"

namespace stampede::app {
namespace {

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
  recipe = fit_worker_recipe(RunConfig(), {}, {});
  recipe.lines.emplace_back("no_such_option", "1");
  try {
    worker_measurers(recipe);
    FAIL() << "a line no option is was accepted";
  } catch (const std::exception& e) {
    EXPECT_NE(std::string(e.what()).find("no_such_option"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace stampede::app
