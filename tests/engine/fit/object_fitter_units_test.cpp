// Tests for the joint fits' units (engine/fit/object_fitter, FitUnits over an object's cutouts): the
// same object with its pixels times s and its weights over s^2 (flux-calibrated tiles, ~1e-10 per
// pixel; very bright data) is the same fit. Four noisy epochs with their own zero points, three
// bands, and bord's single-component fits: at s a power of two every field is the unscaled fit's
// exactly (amplitudes and fluxes times s); at s = 1e-10 and 1e6 the shape, errors, chi2 and status
// agree to rounding, amplitudes and fluxes scaled by s.
#include "engine/fit/object_fitter.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <random>
#include <string>
#include <string_view>
#include <vector>

#include "support/sky_epochs.hpp"

namespace stampede {
namespace {

using testing::SkyEpoch;
using testing::SkyGalaxy;

// Scales that are powers of two (the change of units is exact) and two that are not.
const double kExactScales[] = {0x1p-34, 0x1p20};
const double kScales[] = {1e-10, 1e6};
// The largest relative change of any compared field at a scale that is not a power of two. The
// scaled data differ from the unscaled by rounding (~1e-16 relative), which the fit passes on
// amplified by the problem's conditioning and its stopping rules.
constexpr double kRelative = 1e-9;

// An object: each band's epochs (noise sigma 2, weights 1/4, random frames and PSFs, each epoch's
// zero point its own: data = flux_scale x model + noise), one shape, the bands' fluxes apart.
using Object = std::vector<std::vector<SkyEpoch>>;

Object make_object(std::uint32_t seed, int n_bands, int per_band) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(-1, 1);
  std::normal_distribution<double> noise(0, 2);
  Object object(static_cast<std::size_t>(n_bands));
  for (int b = 0; b < n_bands; ++b) {
    const SkyGalaxy g{0.25, -0.15, 0.6, 0.02, -0.03, 300.0 + 150 * b, 1200.0 - 200 * b};
    for (int k = 0; k < per_band; ++k) {
      SkyEpoch e;
      e.frame = testing::random_frame(rng);
      e.psf = testing::moffat_psf(3.6 - 0.3 * b + 0.3 * u(rng), 0.05 * u(rng), 0.05 * u(rng));
      e.flux_scale = 1 + 0.2 * u(rng);
      e.pixels = testing::draw(g, e.frame, e.psf);
      for (double& v : e.pixels) v = e.flux_scale * v + noise(rng);
      e.weight.assign(e.pixels.size(), 0.25);
      object[static_cast<std::size_t>(b)].push_back(std::move(e));
    }
  }
  return object;
}

// The object with its pixels times s and its weights over s^2.
Object scaled(Object object, double s) {
  for (auto& band : object)
    for (SkyEpoch& e : band) {
      for (double& v : e.pixels) v *= s;
      for (double& w : e.weight) w /= s * s;
    }
  return object;
}

MultiBandFitResult fit(ObjectFitter& fitter, Object& object) {
  std::vector<Observation> data;
  for (std::size_t b = 0; b < object.size(); ++b)
    for (const Observation& o : testing::epoch_data(fitter.renderer_for(testing::kEpochBox), object[b], static_cast<int>(b)))
      data.push_back(o);
  return testing::fit_bands(fitter, data, static_cast<int>(object.size()));
}

struct Change {
  double relative = 0;
  std::string field;  // where it is largest
};

// The largest relative change of `b` (the data times s) against `a`: the shape, e's errors, chi2
// and S/N (unchanged by the scale), the amplitudes and fluxes over s. Status, flags and the pixel
// count must be equal.
Change largest_change(const MultiBandFitResult& a, const MultiBandFitResult& b, double s, const std::string& at) {
  EXPECT_EQ(b.fit.status, a.fit.status) << at;
  EXPECT_EQ(b.fit.flags, a.fit.flags) << at;
  EXPECT_EQ(b.fit.n_pixels, a.fit.n_pixels) << at;
  Change c;
  auto track = [&](double scaled, double base, std::string_view field) {
    double d = std::abs(scaled - base) / std::abs(base);
    if (std::isnan(d)) d = INFINITY;
    if (d > c.relative || c.field.empty()) c.relative = std::max(c.relative, d), c.field = std::string(field);
  };
  for (Param q : {Param::kE1, Param::kE2, Param::kRadius, Param::kX0, Param::kY0})
    track(b.fit.params[index(q)], a.fit.params[index(q)], param_name(q));
  track(b.fit.e1_err, a.fit.e1_err, "e1_err");
  track(b.fit.e2_err, a.fit.e2_err, "e2_err");
  track(b.fit.chi2, a.fit.chi2, "chi2");
  track(b.fit.snr, a.fit.snr, "snr");
  track(b.fit.flux / s, a.fit.flux, "flux");
  for (std::size_t k = 0; k < a.bands.size(); ++k) {
    const BandFit &x = a.bands[k], &y = b.bands[k];
    const std::string band = "band " + std::to_string(k) + " ";
    if (x.bulge_a != 0) track(y.bulge_a / s, x.bulge_a, band + "bulge_a");  // bord's fixed one stays 0
    if (x.disc_a != 0) track(y.disc_a / s, x.disc_a, band + "disc_a");
    track(y.flux / s, x.flux, band + "flux");
    track(y.snr, x.snr, band + "snr");
  }
  return c;
}

// Every scale's fit of `object` against the unscaled one: exact at powers of two (the same
// iterations too), within kRelative otherwise.
void expect_scale_free(const Object& object, const FitterOptions& options, const std::string& what) {
  ObjectFitter fitter(options);
  Object unscaled = object;
  const MultiBandFitResult base = fit(fitter, unscaled);
  ASSERT_EQ(base.fit.status, FitStatus::kOk) << what;
  for (double s : kExactScales) {
    Object data = scaled(object, s);
    const MultiBandFitResult r = fit(fitter, data);
    const std::string at = what + " at scale 2^" + std::to_string(std::ilogb(s));
    EXPECT_EQ(r.fit.iterations, base.fit.iterations) << at;
    const Change c = largest_change(base, r, s, at);
    EXPECT_EQ(c.relative, 0.0) << at << ": " << c.field;
  }
  for (double s : kScales) {
    Object data = scaled(object, s);
    const MultiBandFitResult r = fit(fitter, data);
    const std::string at = what + " at scale " + std::to_string(s);
    const Change c = largest_change(base, r, s, at);
    std::printf("%s, scale %g: largest relative change %.2e (%s); e (%+.12f, %+.12f) vs (%+.12f, %+.12f); %d vs %d "
                "iterations\n",
                what.c_str(), s, c.relative, c.field.c_str(), r.fit.params[index(Param::kE1)],
                r.fit.params[index(Param::kE2)], base.fit.params[index(Param::kE1)], base.fit.params[index(Param::kE2)],
                r.fit.iterations, base.fit.iterations);
    EXPECT_LE(c.relative, kRelative) << at << ": " << c.field;
  }
}

FitterOptions joint_options() {
  FitterOptions o = testing::exact_fit_options();
  o.project_amplitudes = false;
  return o;
}

// bord's fits (app/survey_object_fit): one amplitude fixed at 0.
FitterOptions single_component(Param zero) {
  FitterOptions o = testing::exact_fit_options();
  o.params[zero].free = false;
  o.params[zero].start = 0;
  return o;
}

TEST(ObjectFitterUnits, FourEpochsAreTheSameFitAtAnyDataScale) {
  const Object object = make_object(41, 1, 4);
  expect_scale_free(object, testing::exact_fit_options(), "4 epochs, amplitudes projected");
  expect_scale_free(object, joint_options(), "4 epochs, amplitudes free");
}

TEST(ObjectFitterUnits, ThreeBandsAreTheSameFitAtAnyDataScale) {
  const Object object = make_object(42, 3, 2);
  expect_scale_free(object, testing::exact_fit_options(), "3 bands, amplitudes projected");
  expect_scale_free(object, joint_options(), "3 bands, amplitudes free");
}

TEST(ObjectFitterUnits, BordsSingleComponentFitsAreTheSameAtAnyDataScale) {
  const Object one = make_object(43, 1, 4), three = make_object(44, 3, 2);
  for (Param zero : {Param::kBulgeA, Param::kDiscA}) {
    const std::string model = zero == Param::kBulgeA ? "pure disc" : "pure bulge";
    expect_scale_free(one, single_component(zero), model + ", 4 epochs");
    expect_scale_free(three, single_component(zero), model + ", 3 bands");
  }
}

}  // namespace
}  // namespace stampede
