// Fitting one stamp: errors and S/N, bad input, option checks (the noise-free recovery of the GalSim
// reference cases is in tests/engine/render/renderer_contract_test.cpp, per renderer).
#include "engine/fit/fitter.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <limits>

#include "engine/render/psf_kernel.hpp"
#include "support/reference_data.hpp"

namespace stampede {
namespace {

std::shared_ptr<const PsfKernel> kernel_for(const FitterOptions& fo, const PsfModel& psf, FftPlanCache& plans) {
  std::string err;
  auto k = PsfKernel::build(psf, GridGeometry(fo.render), plans, &err);
  EXPECT_TRUE(k) << err;
  return k;
}

// The reported errors and S/N follow the weights: with noise sigma, snr = sqrt(sum m^2) / sigma.
TEST(Fitter, ReportsErrorsSnrAndFluxesWithNoise) {
  FftPlanCache plans(FftPlanning::kEstimate);
  const auto cases = testing::load_render_cases();
  const auto& c = cases[9];
  FitterOptions fo;
  fo.renderer = RendererKind::kUpsampled;  // kernel_for's kind
  fo.render.stamp_size = c.stamp;
  fo.noise_sigma = 0.5;
  Fitter fitter(fo, kernel_for(fo, testing::case_psf(c), plans), plans);
  const FitResult r = fitter.fit(c.image);
  ASSERT_EQ(r.status, FitStatus::kOk);
  double s2 = 0;
  for (double v : c.image) s2 += v * v;
  EXPECT_NEAR(r.snr, std::sqrt(s2) / 0.5, 1e-2 * std::sqrt(s2) / 0.5);
  EXPECT_GT(r.e1_err, 0);
  EXPECT_LT(r.e1_err, 0.05);
  EXPECT_NEAR(r.flux, c.bulge_flux + c.disc_flux, 5.0);
  EXPECT_NEAR(r.likelihood, -0.5 * r.chi2, 1e-12);
  EXPECT_EQ(r.n_pixels, c.stamp * c.stamp);
  EXPECT_GT(r.iterations, 0);
  EXPECT_GE(r.evaluations, r.iterations);
  EXPECT_TRUE(IsConverged(r.stop_reason));
  EXPECT_LE(r.stop_value, r.stop_threshold);
}

class FitterBadInput : public ::testing::Test {
 protected:
  FftPlanCache plans{FftPlanning::kEstimate};
  testing::RenderCase c = testing::load_render_cases()[6];
  FitterOptions fo = [this] {
    FitterOptions o;
    o.renderer = RendererKind::kUpsampled;  // kernel_for's kind
    o.render.stamp_size = c.stamp;
    return o;
  }();
};

TEST_F(FitterBadInput, NanAndInfPixelsGiveBadPixels) {
  Fitter fitter(fo, kernel_for(fo, testing::case_psf(c), plans), plans);
  std::vector<double> img = c.image;
  img[100] = std::numeric_limits<double>::quiet_NaN();
  EXPECT_EQ(fitter.fit(img).status, FitStatus::kBadPixels);
  img[100] = std::numeric_limits<double>::infinity();
  EXPECT_EQ(fitter.fit(img).status, FitStatus::kBadPixels);
  // A NaN under zero weight is masked, not fatal.
  std::vector<double> w(img.size(), 1.0);
  w[100] = 0.0;
  const FitResult r = fitter.fit(img, w);
  EXPECT_EQ(r.status, FitStatus::kOk);
  EXPECT_TRUE(r.flags & kFlagMaskedPixels);
  EXPECT_TRUE(std::isfinite(r.chi2));
  // Losing one pixel of a noise-free stamp must not move the answer.
  EXPECT_NEAR(r.params[index(Param::kE1)], c.e1, 2e-3);
  EXPECT_NEAR(r.params[index(Param::kE2)], c.e2, 2e-3);
}

TEST_F(FitterBadInput, AllZeroOrZeroWeightGiveNoData) {
  Fitter fitter(fo, kernel_for(fo, testing::case_psf(c), plans), plans);
  std::vector<double> zeros(c.image.size(), 0.0);
  EXPECT_EQ(fitter.fit(zeros).status, FitStatus::kNoData);
  std::vector<double> w(c.image.size(), 0.0);
  EXPECT_EQ(fitter.fit(c.image, w).status, FitStatus::kNoData);
  w.assign(w.size(), -1.0);
  EXPECT_EQ(fitter.fit(c.image, w).status, FitStatus::kBadPixels);
  const FitResult r = fitter.fit(zeros);
  EXPECT_TRUE(std::isnan(r.params[index(Param::kE1)]));  // NaN: not computed
}

// A flat stamp holds no galaxy (the model has no background to fit it with): like an all-zero
// stamp it is not fitted, whatever its level, and a masked pixel does not make it a galaxy.
TEST_F(FitterBadInput, FlatStampGivesNoData) {
  Fitter fitter(fo, kernel_for(fo, testing::case_psf(c), plans), plans);
  for (double level : {3e38, 1e-38, 1.0, -2.5}) {
    std::vector<double> flat(c.image.size(), level);
    const FitResult r = fitter.fit(flat);
    EXPECT_EQ(r.status, FitStatus::kNoData) << "flat stamp of " << level;
    EXPECT_TRUE(std::isnan(r.params[index(Param::kE1)])) << "flat stamp of " << level;
    std::vector<double> w(flat.size(), 1.0);
    w[7] = 0.0;
    flat[7] = std::numeric_limits<double>::quiet_NaN();
    EXPECT_EQ(fitter.fit(flat, w).status, FitStatus::kNoData) << "masked flat stamp of " << level;
  }
}

TEST_F(FitterBadInput, UnnormalisablePsfImageGivesPsfFailure) {
  PsfModel psf;
  psf.kind = PsfKind::kImage;
  auto img = std::make_shared<PsfImage>();
  img->nx = img->ny = 9;
  img->pixels.assign(81, 0.0);
  psf.image = img;
  std::string err;
  auto k = PsfKernel::build(psf, GridGeometry(fo.render), plans, &err);
  EXPECT_FALSE(k);
  EXPECT_NE(err.find("cannot be normalised"), std::string::npos) << err;
  Fitter fitter(fo, k, plans);
  EXPECT_EQ(fitter.fit(c.image).status, FitStatus::kPsfFailure);
}

TEST_F(FitterBadInput, StartWithoutAModelGivesModelFailure) {
  Fitter fitter(fo, kernel_for(fo, testing::case_psf(c), plans), plans);
  ParamVector start = testing::case_truth(c);
  start[index(Param::kRadiusRatio)] = NAN;
  const FitResult r = fitter.fit_from(c.image, {}, start);
  EXPECT_EQ(r.status, FitStatus::kModelFailure);
  // No model, no chi2: NaN, not the paper's "2 per pixel", which reads as a good fit of faint data.
  EXPECT_TRUE(std::isnan(r.chi2)) << r.chi2;
  EXPECT_TRUE(std::isnan(r.likelihood)) << r.likelihood;
  EXPECT_EQ(r.n_pixels, c.stamp * c.stamp);
}

// Invalid options are rejected up front with the option's name, its value and the constraint.
TEST(FitterOptions, InvalidOptionsNameTheOption) {
  struct Bad {
    void (*mutate)(FitterOptions&);
    const char* expect;
  };
  const Bad bad[] = {
      {[](FitterOptions& o) { o.render.upsampling = -2; }, "upsampling = -2"},
      {[](FitterOptions& o) { o.render.n_central_pixel_upsampling = 0; }, "n_central_pixel_upsampling = 0"},
      {[](FitterOptions& o) { o.render.n_central_pixels_to_upsample = -1; }, "n_central_pixels_to_upsample = -1"},
      {[](FitterOptions& o) { o.render.padding = -3; }, "padding = -3"},
      {[](FitterOptions& o) { o.render.stamp_size = 1; }, "stamp_size = 1"},
      {[](FitterOptions& o) { o.lm.eps2 = 2.0; }, "levmar_eps2 = 2"},
      {[](FitterOptions& o) { o.lm.eps4 = -1e-3; }, "levmar_eps4 = -0.001"},
      {[](FitterOptions& o) { o.lm.init_mu = 0; }, "levmar_LM_INIT_MU = 0"},
      {[](FitterOptions& o) { o.lm.max_iterations = 0; }, "minimizer_max_iterations = 0"},
      {[](FitterOptions& o) { o.noise_sigma = -1; }, "noise_sigma = -1"},
      {[](FitterOptions& o) { o.params[Param::kBulgeIndex].free = true; }, "'bulge_index' cannot be free"},
      {[](FitterOptions& o) { o.model.ellipticity_mirror = 1.5; }, "ellipticity_mirror = 1.5"},
  };
  for (const Bad& b : bad) {
    FitterOptions o;
    b.mutate(o);
    std::string why;
    EXPECT_FALSE(o.IsValid(&why)) << b.expect;
    EXPECT_NE(why.find(b.expect), std::string::npos) << "message '" << why << "' lacks '" << b.expect << "'";
    FftPlanCache plans(FftPlanning::kEstimate);
    EXPECT_THROW(Fitter(o, nullptr, plans), std::invalid_argument);
  }
  PsfModel psf;
  psf.moffat.beta = 0.8;
  std::string why;
  EXPECT_FALSE(psf.IsValid(&why));
  EXPECT_NE(why.find("psf_beta = 0.8"), std::string::npos) << why;
  PsfKind t;
  EXPECT_FALSE(parse_psf_kind("gaussian", &t));
  EXPECT_TRUE(parse_psf_kind("airy", &t));
  EXPECT_EQ(t, PsfKind::kAiry);
}

}  // namespace
}  // namespace stampede
