// Noise-free ring tests recover a known shear; the GREAT08 size definition matches GalSim's.
#include "engine/ring_test.hpp"

#include <gtest/gtest.h>

#include <cstdio>

namespace stampede {
namespace {

// The GalSim GREAT08-mini run_info.json: size 1.4 with a beta = 3, FWHM 2.85 Moffat gives
// hlr_disc_only = 1.267388 and hlr_bulge_only = 2.991651 (GalSim's own FWHM estimate; ours
// interpolates the profile linearly, hence the 1% tolerance).
TEST(RingTest, SizeRatioMatchesGalSimCalibration) {
  FftPlanCache plans(FftPlanning::kEstimate);
  PsfOptions psf;
  psf.moffat = {3.0, 2.85, 0.0, 0.05, 0.0};
  const double disc = half_light_radius_for_size_ratio(1.0, 1.4, psf, plans);
  const double bulge = half_light_radius_for_size_ratio(4.0, 1.4, psf, plans);
  std::printf("size 1.4: disc hlr %.4f (GalSim 1.2674), bulge hlr %.4f (GalSim 2.9917)\n", disc, bulge);
  EXPECT_NEAR(disc / 1.267388201586823, 1.0, 1e-2);
  EXPECT_NEAR(bulge / 2.9916512065943093, 1.0, 1e-2);
}

// A model-matched galaxy (exponential disc; co-elliptical bulge + disc) at the fiducial size,
// drawn at high accuracy and fitted at the defaults, gives the input shear back.
TEST(RingTest, ModelMatchedGalaxiesRecoverShearAtDefaults) {
  FftPlanCache plans(FftPlanning::kEstimate);
  PsfOptions psf;
  psf.moffat = {3.5, 2.85, 0.0, 0.0, 0.0};
  for (double bulge_fraction : {0.0, 0.5}) {
    RingTestConfig cfg;
    cfg.psf = psf;
    cfg.bulge_fraction = bulge_fraction;
    cfg.half_light_radius = half_light_radius_for_size_ratio(1.0, 1.4, psf, plans);
    cfg.fit.render.stamp_size = 25;
    const RingTestResult r = run_ring_test(cfg, plans);
    std::printf("B/T %.1f hlr %.3f: m1 %+.2e m2 %+.2e c1 %+.1e c2 %+.1e\n", bulge_fraction, cfg.half_light_radius, r.m1,
                r.m2, r.c1, r.c2);
    EXPECT_EQ(r.failed, 0);
    EXPECT_LT(std::abs(r.m1), 4e-3);
    EXPECT_LT(std::abs(r.m2), 4e-3);
    // A round PSF and a symmetric ring leave no additive bias beyond rounding.
    EXPECT_LT(std::abs(r.c1), 1e-4);
    EXPECT_LT(std::abs(r.c2), 1e-4);
  }
}

}  // namespace
}  // namespace stampede
