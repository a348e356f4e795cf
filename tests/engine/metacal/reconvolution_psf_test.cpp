// Tests for the reconvolution PSF's search (engine/metacal/reconvolution_psf): an image PSF's
// Gamma is searched for on a ladder of 3 % rungs, bisecting on the filters' coarse check and then
// building in full. What it finds must be what building every rung in full from the first would
// find: the narrowest rung whose filters every cutout accepts. That rests on the coarse check
// failing wherever a full build fails and, along the ladder, never failing above a rung where it
// passed; both are checked here on PSF images of several widths seen through random frames.
#include "engine/metacal/reconvolution_psf.hpp"

#include <gtest/gtest.h>

#include <cstdio>
#include <memory>
#include <random>
#include <vector>

#include "engine/sim/sim_renderer.hpp"
#include "support/sky_epochs.hpp"

namespace stampede {
namespace {

constexpr int kPeriod = 96;  // MetacalImager::padded_size(48)

// A Moffat's pixel-integrated 25 x 25 image, as a PSFEx model is handed to metacal.
PsfModel psf_image(double fwhm, double e1, double e2) {
  const PsfModel moffat = testing::moffat_psf(fwhm, e1, e2);
  auto image = std::make_shared<PsfImage>();
  image->nx = image->ny = 25;
  image->pixels.resize(25 * 25);
  image->pixel_integrated = true;
  SimWorkspace ws;
  SimRenderer(moffat, SimRenderer::Options{}).render_psf(25, 1.0, 12.0, 12.0, true, image->pixels, ws);
  return PsfModel::Image(image);
}

struct Cutouts {
  std::vector<PsfModel> psfs;
  std::vector<MetacalEpochPsf> epochs;
};

Cutouts cutouts(std::uint32_t seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(-1, 1);
  Cutouts c;
  c.psfs.reserve(4);
  for (int k = 0; k < 4; ++k) c.psfs.push_back(psf_image((0.95 + 0.15 * u(rng)) / 0.263, 0.04 * u(rng), 0.04 * u(rng)));
  for (const PsfModel& p : c.psfs) c.epochs.push_back({&p, testing::random_frame(rng), kPeriod});
  return c;
}

bool every_cutout_builds(const Cutouts& c, double fwhm, double beta) {
  for (const MetacalEpochPsf& e : c.epochs) {
    std::string error;
    const auto observed = MetacalFilters::observe(*e.psf, e.period, &error);
    if (!observed) return false;
    if (!MetacalFilters::build(*observed, round_on_sky(beta, fwhm, e.frame), MetacalOptions{}.step, &error, 1.01, e.frame))
      return false;
  }
  return true;
}

TEST(SkyReconvolution, AnImagePsfsGammaIsTheNarrowestRungEveryCutoutBuilds) {
  for (std::uint32_t seed : {1u, 2u, 3u}) {
    const Cutouts c = cutouts(seed);
    SkyReconvolution out;
    std::string error;
    ASSERT_TRUE(sky_reconvolution(c.epochs, MetacalOptions{}, &out, &error)) << error;
    ASSERT_EQ(out.filters.size(), 4u);
    for (const auto& f : out.filters) ASSERT_TRUE(f);
    EXPECT_TRUE(every_cutout_builds(c, out.fwhm, out.beta)) << "seed " << seed;
    // The rung below is refused by some cutout's full build (the search did not stop early).
    EXPECT_FALSE(every_cutout_builds(c, out.fwhm / 1.03, out.beta)) << "seed " << seed << ": " << out.fwhm;
  }
}

TEST(SkyReconvolution, TheCoarseCheckFailsWhereABuildFailsAndNeverAgainAboveARungWhereItPassed) {
  int coarse_only = 0, both = 0;
  for (std::uint32_t seed : {11u, 12u, 13u}) {
    const Cutouts c = cutouts(seed);
    for (const MetacalEpochPsf& e : c.epochs) {
      std::string error;
      const auto observed = MetacalFilters::observe(*e.psf, e.period, &error);
      ASSERT_TRUE(observed) << error;
      bool passed = false;
      for (double fwhm = 0.6; fwhm < 2.0; fwhm *= 1.03) {
        const PsfModel gamma = round_on_sky(3.0, fwhm, e.frame);
        const bool coarse = MetacalFilters::passes_coarse_check(*observed, gamma, 0.01, 1.01, e.frame);
        const bool full = MetacalFilters::build(*observed, gamma, 0.01, &error, 1.01, e.frame) != nullptr;
        EXPECT_TRUE(coarse || !full) << "seed " << seed << " FWHM " << fwhm;
        EXPECT_TRUE(coarse || !passed) << "seed " << seed << " FWHM " << fwhm;
        passed = passed || coarse;
        coarse_only += coarse && !full;
        both += coarse && full;
      }
      EXPECT_TRUE(passed) << "seed " << seed;
    }
  }
  // The ladder crosses from refused to accepted Gammas within its range for every cutout.
  EXPECT_GT(both, 0);
  std::printf("rungs that pass the coarse check but not the full build: %d (of %d passing)\n", coarse_only,
              coarse_only + both);
}

TEST(ReconvolutionFilters, AnImagePsfsGammaIsTheNarrowestRungThatBuilds) {
  for (double fwhm : {2.5, 3.2, 4.0}) {
    const PsfModel psf = psf_image(fwhm, 0.03, -0.02);
    std::string error;
    const auto chosen = reconvolution_filters(psf, MetacalOptions{}, kPeriod, &error);
    ASSERT_TRUE(chosen) << error;
    const double gamma = chosen->reconvolution().moffat.fwhm;
    kernels::MoffatProfile narrower;
    narrower.beta = 3.0;
    narrower.fwhm = gamma / 1.03;
    EXPECT_FALSE(MetacalFilters::build(psf, PsfModel::Moffat(narrower), MetacalOptions{}.step, kPeriod, &error))
        << "PSF FWHM " << fwhm << ": Gamma " << gamma;
  }
}

}  // namespace
}  // namespace stampede
