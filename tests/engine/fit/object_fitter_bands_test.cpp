// Tests for ObjectFitter's fits over bands (engine/fit/object_fitter): three noise-free bands of four
// epochs each (random frames, per-band PSFs, per-band bulge and disc fluxes) give the sky shape and
// every band's fluxes back; one band of several is the one-band fit bit for bit; identical bands divide
// the shape's errors by sqrt(bands); a band without cutouts is left out; bad band indices throw.
#include "engine/fit/object_fitter.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <cstring>
#include <random>
#include <stdexcept>
#include <vector>

#include "support/sky_epochs.hpp"

namespace stampede {
namespace {

using testing::kEpochBox;
using testing::SkyEpoch;
using testing::SkyGalaxy;

// Band b's epochs of galaxy g (its fluxes those of g), each in a random frame with a PSF of about
// `fwhm` pixels.
std::vector<SkyEpoch> band_epochs(const SkyGalaxy& g, double fwhm, int n, std::mt19937& rng) {
  std::uniform_real_distribution<double> u(-1, 1);
  std::vector<SkyEpoch> epochs(static_cast<std::size_t>(n));
  for (SkyEpoch& e : epochs) {
    e.frame = testing::random_frame(rng);
    e.psf = testing::moffat_psf(fwhm + 0.3 * u(rng), 0.05 * u(rng), 0.05 * u(rng));
    e.pixels = testing::draw(g, e.frame, e.psf);
    e.weight.assign(kEpochBox * kEpochBox, 1.0);
  }
  return epochs;
}

// Must-show 1's core: the shape to 1e-6 (a shear of 0.02 to 5e-5 relative) and each band's total
// flux to 1e-6 relative, from the moments start of the first cutout.
TEST(ObjectFitterBands, NoiseFreeBandsGiveTheShapeAndEachBandsFluxesBack) {
  std::mt19937 rng(41);
  std::uniform_real_distribution<double> u(-1, 1);
  ObjectFitter fitter(testing::exact_fit_options());
  double worst_e = 0, worst_flux = 0;
  for (int galaxy = 0; galaxy < 2; ++galaxy) {
    const SkyGalaxy shape{0.4 * u(rng), 0.4 * u(rng), 0.55 + 0.15 * u(rng), 0.05 * u(rng), 0.05 * u(rng), 0, 0};
    std::vector<SkyGalaxy> bands;
    std::vector<std::vector<SkyEpoch>> epochs;
    std::vector<Observation> data;
    for (int b = 0; b < 3; ++b) {
      SkyGalaxy g = shape;
      g.bulge_flux = (100 + 150 * b) * (1 + 0.2 * u(rng));  // redder bands: more bulge
      g.disc_flux = (900 - 150 * b) * (1 + 0.2 * u(rng));
      bands.push_back(g);
      epochs.push_back(band_epochs(g, 3.8 - 0.3 * b, 4, rng));
    }
    for (int b = 0; b < 3; ++b)
      for (const Observation& e : testing::epoch_data(fitter.renderer_for(kEpochBox), epochs[b], b)) data.push_back(e);
    const MultiBandFitResult r = testing::fit_bands(fitter, data, 3);
    ASSERT_EQ(r.fit.status, FitStatus::kOk) << "galaxy " << galaxy;
    const double d1 = r.fit.params[index(Param::kE1)] - shape.e1, d2 = r.fit.params[index(Param::kE2)] - shape.e2;
    worst_e = std::max({worst_e, std::abs(d1), std::abs(d2)});
    EXPECT_NEAR(r.fit.params[index(Param::kRadius)], shape.radius, 1e-6 * shape.radius);
    EXPECT_TRUE(std::isnan(r.fit.params[index(Param::kBulgeA)]));
    ASSERT_EQ(r.bands.size(), 3u);
    double total = 0;
    for (int b = 0; b < 3; ++b) {
      const BandFit& f = r.bands[b];
      const double truth = bands[b].bulge_flux + bands[b].disc_flux;
      EXPECT_EQ(f.n_epochs, 4);
      worst_flux = std::max(worst_flux, std::abs(f.flux / truth - 1));
      EXPECT_NEAR(f.bulge_flux, bands[b].bulge_flux, 1e-4 * truth) << "band " << b;
      EXPECT_GT(f.snr, 0);
      total += f.flux;
      std::printf("galaxy %d band %d: flux %.6f (true %.6f), bulge %.4f (true %.4f), S/N %.1f\n", galaxy, b, f.flux, truth,
                  f.bulge_flux, bands[b].bulge_flux, f.snr);
    }
    EXPECT_DOUBLE_EQ(r.fit.flux, total);
    std::printf("galaxy %d: e fitted - true (%+.2e, %+.2e), %d iterations\n", galaxy, d1, d2, r.fit.iterations);
  }
  EXPECT_LT(worst_e, 1e-6);
  EXPECT_LT(worst_flux, 1e-6);
}

// An object seen in one band of several is that band's fit, every field bit for bit (a one-band
// run's rows are the single tile's), its amplitudes reported per band.
TEST(ObjectFitterBands, OneBandOfSeveralIsTheOneBandFitBitForBit) {
  std::mt19937 rng(8);
  std::normal_distribution<double> noise(0, 1);
  const SkyGalaxy g{0.2, -0.1, 0.6, 0.01, -0.02, 300, 1100};
  std::vector<SkyEpoch> epochs = band_epochs(g, 3.6, 4, rng);
  for (SkyEpoch& e : epochs)
    for (double& v : e.pixels) v += noise(rng);
  ObjectFitter bands(testing::exact_fit_options());
  ObjectFitter single(testing::exact_fit_options());
  const std::vector<Observation> a = testing::epoch_data(bands.renderer_for(kEpochBox), epochs);
  const std::vector<Observation> b = testing::epoch_data(single.renderer_for(kEpochBox), epochs);
  const MultiBandFitResult joint = testing::fit_bands(bands, a, 3);
  const FitResult one = single.fit(b);
  ASSERT_EQ(one.status, FitStatus::kOk);
  EXPECT_EQ(joint.fit.status, one.status);
  EXPECT_EQ(joint.fit.iterations, one.iterations);
  for (int k = 0; k < kNumParams; ++k) {
    if (k == index(Param::kBulgeA) || k == index(Param::kDiscA)) {
      EXPECT_TRUE(std::isnan(joint.fit.params[k])) << param_name(static_cast<Param>(k));
      continue;
    }
    EXPECT_EQ(std::memcmp(&joint.fit.params[k], &one.params[k], sizeof(double)), 0) << param_name(static_cast<Param>(k));
    EXPECT_EQ(std::memcmp(&joint.fit.errors[k], &one.errors[k], sizeof(double)), 0) << param_name(static_cast<Param>(k));
  }
  EXPECT_EQ(joint.fit.chi2, one.chi2);
  EXPECT_EQ(joint.fit.snr, one.snr);
  EXPECT_EQ(joint.bands[0].flux, one.flux);
  EXPECT_EQ(joint.bands[0].snr, one.snr);
  EXPECT_EQ(joint.bands[0].disc_a, one.params[index(Param::kDiscA)]);
  EXPECT_EQ(joint.bands[1].n_epochs, 0);
  EXPECT_TRUE(std::isnan(joint.bands[2].flux));
}

// Must-show 3's law, exactly: the same cutouts in three bands (the same fluxes) hold three times the
// shape's information, each band's amplitudes being its own: e's errors are one band's / sqrt(3).
TEST(ObjectFitterBands, IdenticalBandsDivideTheShapeErrorsByTheRootOfTheirNumber) {
  std::mt19937 rng(3);
  std::normal_distribution<double> noise(0, 1);
  const SkyGalaxy g{0.15, 0.25, 0.6, 0, 0, 300, 1200};
  std::vector<SkyEpoch> epochs = band_epochs(g, 3.6, 2, rng);
  for (SkyEpoch& e : epochs)
    for (double& v : e.pixels) v += noise(rng);
  // Both fits to their optimum, not to where eps4 stops them: the one-band fit's Gauss-Newton
  // decrease at a given offset is a third of the joint's, so at the default eps4 they stop at
  // offsets that differ by ~1e-3 of the errors (the fluxes by ~1e-5).
  FitterOptions o = testing::exact_fit_options();
  o.lm.eps4 = 1e-12;
  ObjectFitter fitter(o);
  std::vector<Observation> three;
  for (int b = 0; b < 3; ++b)
    for (const Observation& e : testing::epoch_data(fitter.renderer_for(kEpochBox), epochs, b)) three.push_back(e);
  const MultiBandFitResult one = testing::fit_bands(fitter, std::span<const Observation>(three.data(), 2), 3);
  const MultiBandFitResult joint = testing::fit_bands(fitter, three, 3);
  ASSERT_EQ(one.fit.status, FitStatus::kOk);
  ASSERT_EQ(joint.fit.status, FitStatus::kOk);
  const double r1 = joint.fit.e1_err * std::sqrt(3.0) / one.fit.e1_err, r2 = joint.fit.e2_err * std::sqrt(3.0) / one.fit.e2_err;
  std::printf("e errors one band (%.4e, %.4e), three (%.4e, %.4e): x sqrt(3) / one's = %.8f %.8f\n", one.fit.e1_err,
              one.fit.e2_err, joint.fit.e1_err, joint.fit.e2_err, r1, r2);
  EXPECT_NEAR(r1, 1, 1e-5);
  EXPECT_NEAR(r2, 1, 1e-5);
  EXPECT_NEAR(joint.fit.params[index(Param::kE1)], one.fit.params[index(Param::kE1)], 1e-6);
  EXPECT_NEAR(joint.fit.snr, std::sqrt(3.0) * one.fit.snr, 1e-6 * joint.fit.snr);
  // Bands 1 and 2 had no cutouts in the first fit: left out, their fluxes NaN.
  EXPECT_EQ(one.bands[1].n_epochs, 0);
  EXPECT_TRUE(std::isnan(one.bands[2].flux));
  EXPECT_NEAR(one.bands[0].flux, joint.bands[2].flux, 1e-6 * one.bands[0].flux);
}

TEST(ObjectFitterBands, ABandOutOfRangeOrTooManyBandsThrow) {
  std::mt19937 rng(1);
  const SkyGalaxy g{0.1, 0.1, 0.6, 0, 0, 300, 1000};
  std::vector<SkyEpoch> epochs = band_epochs(g, 3.6, 1, rng);
  ObjectFitter fitter(testing::exact_fit_options());
  const std::vector<Observation> data = testing::epoch_data(fitter.renderer_for(kEpochBox), epochs, 2);
  EXPECT_THROW(fitter.fit(data, 2), std::invalid_argument);
  EXPECT_THROW(fitter.fit(data, kMaxBands + 1), std::invalid_argument);
  EXPECT_THROW(fitter.fit(data, 0), std::invalid_argument);
}

}  // namespace
}  // namespace stampede
