// app/calibration_build: the output is locked for the build's life (issue 17's leftover: `calibrate
// build` took no lock, so two builds could write one table).
#include "app/calibration_build.hpp"

#include <gtest/gtest.h>
#include <unistd.h>

#include <string>

#include "io/durable_file.hpp"
#include "io/output_lock.hpp"
#include "support/error_assertions.hpp"
#include "support/scratch_dir.hpp"

namespace {

using namespace stampede;

TEST(CalibrationBuild, TheOutputIsLockedForTheBuildsLife) {
  const stampede::testing::ScratchDir scratch("stampede_calibration_build_");
  app::CalibrationBuildOptions o;
  o.output = scratch.path("cal.fits");
  app::apply_set(o.config, "noise_sigma=1");
  {
    const app::CalibrationBuild first(o);
    EXPECT_TRUE(io::file_exists(io::OutputLock::path_for(o.output)));
    app::CalibrationBuildOptions again = o;
    again.overwrite = true;  // not a way around the lock
    EXPECT_TRUE(stampede::testing::Contains(
        stampede::testing::error_of<io::FileError>([&] { app::CalibrationBuild second(again); }),
        "'" + o.output + "' is in use by another run: '" + o.output + ".lock' is held by 'pid " +
            std::to_string(getpid())));
  }
  EXPECT_FALSE(io::file_exists(io::OutputLock::path_for(o.output)));  // released with the build
}

}  // namespace
