// Tests for the reconvolution PSF's rules (engine/metacal/reconvolution_psf). The Gaussian rule:
// the PSF's adaptive Gaussian on its major axis, dilated by 1 + 2 step, falling back to the Moffat
// rule under kAuto where its filters are not bounded. The Moffat rule: an image PSF's
// Gamma is searched for on a ladder of 3 % rungs, bisecting on the filters' coarse check and then
// building in full. What it finds must be what building every rung in full from the first would
// find: the narrowest rung whose filters every cutout accepts. That rests on the coarse check
// failing wherever a full build fails and, along the ladder, never failing above a rung where it
// passed; both are checked here on PSF images of several widths seen through random frames.
#include "engine/metacal/reconvolution_psf.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <memory>
#include <random>
#include <string>
#include <tuple>
#include <utility>
#include <vector>

#include "engine/sim/sim_renderer.hpp"
#include "kernels/moments.hpp"
#include "support/sky_epochs.hpp"

namespace stampede {
namespace {

constexpr int kPeriod = 96;  // MetacalImager::padded_size(48)

MetacalOptions with_rule(ReconvolutionRule rule) {
  MetacalOptions o;
  o.reconvolution = rule;
  return o;
}
const MetacalOptions kMoffatRule = with_rule(ReconvolutionRule::kMoffat);

// A profile's pixel-integrated n x n image (each pixel the mean of 9 x 9 point values), centred.
PsfModel pixelated_image(const PsfModel& profile, int n) {
  auto image = std::make_shared<PsfImage>();
  image->nx = image->ny = n;
  image->pixel_integrated = true;
  const double c = 0.5 * (n - 1);
  for (int y = 0; y < n; ++y)
    for (int x = 0; x < n; ++x) {
      double sum = 0;
      for (int j = 0; j < 9; ++j)
        for (int i = 0; i < 9; ++i) sum += profile.x_value(x - c - 0.5 + (i + 0.5) / 9, y - c - 0.5 + (j + 0.5) / 9);
      image->pixels.push_back(sum / 81);
    }
  return PsfModel::Image(image);
}

// The Gaussian rule's Gamma FWHM: the fitted Gaussian's major axis dilated, less the pixel.
double gaussian_rule_fwhm(double major_fwhm, double dilation) {
  const double sigma = dilation * major_fwhm / 2.3548;
  return 2.3548 * std::sqrt(sigma * sigma - 1.0 / 12);
}

// 2.3548 sqrt(lambda_max) of an image's adaptive moments: the Gaussian fitted to it, its major axis.
double adaptive_major_fwhm(const PsfImage& im) {
  const std::vector<double> ones(im.pixels.size(), 1.0);
  const kernels::ImageMoments m = kernels::adaptive_moments(im.pixels, ones, im.nx);
  const double tr = m.xx + m.yy, det = m.xx * m.yy - m.xy * m.xy;
  return 2.3548 * std::sqrt(0.5 * tr + std::sqrt(0.25 * tr * tr - det));
}

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
    if (!MetacalFilters::build(*observed, round_on_sky(beta, fwhm, e.frame), kMoffatRule.step, &error, 1.01, e.frame))
      return false;
  }
  return true;
}

TEST(SkyReconvolution, AnImagePsfsGammaIsTheNarrowestRungEveryCutoutBuilds) {
  for (std::uint32_t seed : {1u, 2u, 3u}) {
    const Cutouts c = cutouts(seed);
    SkyReconvolution out;
    std::string error;
    ASSERT_TRUE(sky_reconvolution(c.epochs, kMoffatRule, &out, &error)) << error;
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
    const auto chosen = reconvolution_filters(psf, kMoffatRule, kPeriod, &error);
    ASSERT_TRUE(chosen) << error;
    const double gamma = chosen->reconvolution().moffat.fwhm;
    kernels::MoffatProfile narrower;
    narrower.beta = 3.0;
    narrower.fwhm = gamma / 1.03;
    EXPECT_FALSE(MetacalFilters::build(psf, PsfModel::Moffat(narrower), MetacalOptions{}.step, kPeriod, &error))
        << "PSF FWHM " << fwhm << ": Gamma " << gamma;
  }
}

TEST(ReconvolutionFilters, TheGaussianRuleIsThePsfsAdaptiveGaussianDilated) {
  // Gaussian PSFs (as the reference shear test's) and elliptical ones: Gamma is round, Gamma x pixel
  // of FWHM (1 + 2 step) x the major axis of the Gaussian fitted to the PSF image, and bounded.
  for (const auto& [fwhm, e1, e2] : {std::tuple{3.6, 0.0, 0.0}, std::tuple{2.6, 0.05, -0.03}, std::tuple{4.5, 0.0, 0.08}}) {
    const PsfModel psf = pixelated_image(PsfModel::Gaussian({fwhm, e1, e2}), 41);
    std::string error;
    for (ReconvolutionRule rule : {ReconvolutionRule::kGauss, ReconvolutionRule::kAuto}) {
      const auto f = reconvolution_filters(psf, with_rule(rule), kPeriod, &error);
      ASSERT_TRUE(f) << error;
      const PsfModel& gamma = f->reconvolution();
      ASSERT_EQ(gamma.kind, PsfKind::kGaussian);
      EXPECT_EQ(gamma.gaussian.e1, 0.0);
      EXPECT_EQ(gamma.gaussian.e2, 0.0);
      EXPECT_NEAR(gamma.fwhm(), gaussian_rule_fwhm(adaptive_major_fwhm(*psf.image), 1.02), 1e-9) << "PSF FWHM " << fwhm;
    }
    // psf_dilation replaces 1 + 2 step.
    MetacalOptions wider = with_rule(ReconvolutionRule::kGauss);
    wider.psf_dilation = 1.2;
    const auto f = reconvolution_filters(psf, wider, kPeriod, &error);
    ASSERT_TRUE(f) << error;
    EXPECT_NEAR(f->reconvolution().fwhm(), gaussian_rule_fwhm(adaptive_major_fwhm(*psf.image), 1.2), 1e-9);
  }
}

TEST(ReconvolutionFilters, AGaussianGammaIsNarrowerThanTheMoffatOverAGaussianPsf) {
  // A Moffat's transform falls as e^-k, a Gaussian PSF's as e^-k^2: the Moffat Gamma must be far
  // wider to stay below the PSF at high k; the Gaussian Gamma needs only the step's dilation.
  const PsfModel psf = pixelated_image(PsfModel::Gaussian({3.6, 0.0, 0.0}), 41);
  std::string error;
  const auto gauss = reconvolution_filters(psf, with_rule(ReconvolutionRule::kGauss), kPeriod, &error);
  const auto moffat = reconvolution_filters(psf, kMoffatRule, kPeriod, &error);
  ASSERT_TRUE(gauss && moffat) << error;
  std::printf("Gaussian PSF FWHM 3.6 px: Gamma gauss FWHM %.3f (noise gain %.4f), moffat FWHM %.3f (noise gain %.4f)\n",
              gauss->reconvolution().fwhm(), gauss->noise_gain(), moffat->reconvolution().fwhm(), moffat->noise_gain());
  EXPECT_GT(moffat->reconvolution().fwhm(), 1.2 * gauss->reconvolution().fwhm());
  EXPECT_LT(gauss->noise_gain(), 1.0);  // still a smoothing: its pixels' noise below the data's
}

TEST(ReconvolutionFilters, APsfWhoseTransformVanishesHasNoGammaUnderAnyRule) {
  // An Airy disc's transform is zero beyond its cut-off: no filter divides by it.
  const PsfModel airy = PsfModel::Airy({2.0, 0.0});
  for (ReconvolutionRule rule : {ReconvolutionRule::kAuto, ReconvolutionRule::kGauss, ReconvolutionRule::kMoffat}) {
    std::string error;
    EXPECT_FALSE(reconvolution_filters(airy, with_rule(rule), kPeriod, &error)) << reconvolution_rule_name(rule);
    EXPECT_FALSE(error.empty());
    if (rule == ReconvolutionRule::kAuto) {
      EXPECT_NE(error.find("neither a Gaussian"), std::string::npos) << error;
    }
  }
}

TEST(ReconvolutionFilters, AutoFallsBackToTheMoffatWhereTheGaussianIsNotBounded) {
  // A third of the light in a narrow core, the rest in a wide halo: the Gaussian fitted to the
  // image is wider than the core, whose transform alone remains at high k (a third of the
  // Gaussian's there and falling slower), so the Gaussian Gamma's filter grows past any bound. gauss refuses it; auto takes the Moffat rule's Gamma.
  auto halo = std::make_shared<PsfImage>();
  const PsfModel core = pixelated_image(PsfModel::Gaussian({2.4, 0.0, 0.0}), 61);
  const PsfModel wide = pixelated_image(PsfModel::Gaussian({9.0, 0.0, 0.0}), 61);
  *halo = *core.image;
  for (std::size_t i = 0; i < halo->pixels.size(); ++i) halo->pixels[i] = (core.image->pixels[i] + 2 * wide.image->pixels[i]) / 3;
  const PsfModel psf = PsfModel::Image(halo);
  std::string error;
  EXPECT_FALSE(reconvolution_filters(psf, with_rule(ReconvolutionRule::kGauss), kPeriod, &error));
  EXPECT_NE(error.find("Gaussian reconvolution PSF"), std::string::npos) << error;
  const auto automatic = reconvolution_filters(psf, with_rule(ReconvolutionRule::kAuto), kPeriod, &error);
  const auto moffat = reconvolution_filters(psf, kMoffatRule, kPeriod, &error);
  ASSERT_TRUE(automatic && moffat) << error;
  EXPECT_EQ(automatic->reconvolution().kind, PsfKind::kMoffat);
  EXPECT_TRUE(automatic->reconvolution() == moffat->reconvolution());
}

TEST(ReconvolutionFilters, OverMoffatPsfsTheGaussianIsAskedForAndAutoKeepsTheMoffat) {
  // The Gaussian fitted to a Moffat: its filters peak at 1.1-1.3 at middle k (the wings steepen the
  // Moffat's transform at low k) and fall at high k, with a quarter of the Moffat rule's noise per
  // pixel. `gauss` builds it; `auto` keeps the Moffat rule's Gamma there (the middle-k gain cost
  // fit --metacal's S/N 20 shear: docs/metacal.md).
  for (double beta : {2.5, 3.5, 4.5}) {
    const PsfModel psf = PsfModel::Moffat({beta, 3.6, 0.0, 0.0, 0.0});
    std::string error;
    const auto gauss = reconvolution_filters(psf, with_rule(ReconvolutionRule::kGauss), kPeriod, &error);
    ASSERT_TRUE(gauss) << "beta " << beta << ": " << error;
    const auto moffat = reconvolution_filters(psf, kMoffatRule, kPeriod, &error);
    ASSERT_TRUE(moffat) << error;
    const auto automatic = reconvolution_filters(psf, with_rule(ReconvolutionRule::kAuto), kPeriod, &error);
    ASSERT_TRUE(automatic) << error;
    std::printf("Moffat PSF beta %.1f FWHM 3.6 px: Gamma gauss FWHM %.3f noise gain %.4f; moffat FWHM %.3f noise gain %.4f\n",
                beta, gauss->reconvolution().fwhm(), gauss->noise_gain(), moffat->reconvolution().fwhm(),
                moffat->noise_gain());
    EXPECT_LT(gauss->noise_gain(), moffat->noise_gain()) << "beta " << beta;
    EXPECT_TRUE(automatic->reconvolution() == moffat->reconvolution()) << "beta " << beta;
  }
}

TEST(SkyReconvolution, OneCutoutWithAUnitJacobianGetsTheSingleStampsGaussian) {
  const PsfModel psf = pixelated_image(PsfModel::Gaussian({3.0, 0.04, 0.02}), 31);
  const MetacalEpochPsf epoch{&psf, PixelFrame(), kPeriod};
  SkyReconvolution sky;
  std::string error;
  ASSERT_TRUE(sky_reconvolution({&epoch, 1}, MetacalOptions{}, &sky, &error)) << error;
  const auto single = reconvolution_filters(psf, MetacalOptions{}, kPeriod, &error);
  ASSERT_TRUE(single) << error;
  EXPECT_EQ(sky.kind, PsfKind::kGaussian);
  EXPECT_EQ(sky.fwhm, single->reconvolution().fwhm());
  EXPECT_TRUE(sky.filters[0]->reconvolution() == single->reconvolution());
  const std::size_t n = static_cast<std::size_t>(kPeriod) * (kPeriod / 2 + 1);
  for (MetacalType t : kMetacalTypes)
    for (std::size_t i = 0; i < n; ++i) ASSERT_EQ(sky.filters[0]->filter(t)[i], single->filter(t)[i]);
}

// A grid stamp is one cutout in its pixel grid (MetacalFitter): its sky Gamma is the single-PSF
// rule's, filters and all, for every rule and dilation, over Moffat PSFs of several profiles and
// ellipticities and a PSF image; where one rule finds no Gamma, neither does the other.
TEST(SkyReconvolution, OneCutoutWithAUnitJacobianGetsTheSinglePsfRulesGamma) {
  std::vector<PsfModel> psfs;
  for (double beta : {2.5, 3.0, 4.5})
    for (double fwhm : {2.0, 2.85, 4.0})
      for (const auto& [e1, e2] : {std::pair{0.0, 0.0}, std::pair{0.0, 0.05}, std::pair{0.1, -0.08}, std::pair{0.2, 0.15}})
        psfs.push_back(PsfModel::Moffat({beta, fwhm, e1, e2, 0.0}));
  psfs.push_back(pixelated_image(PsfModel::Moffat({3.0, 2.85, 0.02, 0.04, 0.0}), 31));
  const std::size_t n = static_cast<std::size_t>(kPeriod) * (kPeriod / 2 + 1);
  int served = 0, cases = 0;
  for (ReconvolutionRule rule : {ReconvolutionRule::kAuto, ReconvolutionRule::kGauss, ReconvolutionRule::kMoffat})
    for (double dilation : {0.0, 1.2})
      for (const PsfModel& psf : psfs) {
        MetacalOptions options = with_rule(rule);
        options.psf_dilation = dilation;
        SCOPED_TRACE(::testing::Message() << "rule " << reconvolution_rule_name(rule) << ", dilation " << dilation
                                          << ", PSF " << psf_kind_name(psf.kind) << " fwhm " << psf.fwhm());
        const MetacalEpochPsf epoch{&psf, PixelFrame(), kPeriod};
        SkyReconvolution sky;
        std::string sky_error, single_error;
        const bool by_sky = sky_reconvolution({&epoch, 1}, options, &sky, &sky_error);
        const auto single = reconvolution_filters(psf, options, kPeriod, &single_error);
        ++cases;
        ASSERT_EQ(by_sky, single != nullptr) << sky_error << " / " << single_error;
        if (!single) continue;
        ++served;
        EXPECT_EQ(sky.fwhm, single->reconvolution().fwhm());
        ASSERT_TRUE(sky.filters[0]->reconvolution() == single->reconvolution());
        EXPECT_EQ(sky.filters[0]->noise_gain(), single->noise_gain());
        for (MetacalType t : kMetacalTypes)
          for (std::size_t i = 0; i < n; ++i) ASSERT_EQ(sky.filters[0]->filter(t)[i], single->filter(t)[i]);
      }
  std::printf("%d of %d cases served by both rules\n", served, cases);
  EXPECT_GT(served, cases / 2);
}

TEST(ReconvolutionRule, NamesParseBack) {
  for (ReconvolutionRule r : {ReconvolutionRule::kAuto, ReconvolutionRule::kGauss, ReconvolutionRule::kMoffat}) {
    ReconvolutionRule parsed;
    ASSERT_TRUE(parse_reconvolution_rule(reconvolution_rule_name(r), &parsed));
    EXPECT_EQ(parsed, r);
  }
  ReconvolutionRule r;
  EXPECT_TRUE(parse_reconvolution_rule("GAUSS", &r));
  EXPECT_FALSE(parse_reconvolution_rule("fitgauss", &r));
}

}  // namespace
}  // namespace stampede
