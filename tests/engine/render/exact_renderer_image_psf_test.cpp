// Tests for image PSFs in the exact renderer (ExactPsf's band-limited image form): a truncated
// Moffat given as pixel-integrated samples draws the galaxies its analytic form draws, to what
// the samples' band limit leaves out; an off-centre, asymmetric image moves and skews the model as
// it should (its transform is complex); the Jacobian matches finite differences.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <memory>
#include <vector>

#include "engine/render/exact_renderer.hpp"
#include "support/jacobian_check.hpp"
#include "engine/sim/sim_renderer.hpp"

namespace stampede {
namespace {

constexpr int kStamp = 39, kPsfSize = 41;

PsfModel moffat(double fwhm, double e1, double e2) {
  PsfModel p;
  p.kind = PsfKind::kMoffat;
  p.moffat = {3.0, fwhm, e1, e2, 18.0};  // truncated: the 41-pixel image holds all its light
  return p;
}

// The PSF's pixel integrals on kPsfSize^2 samples centred at (cx, cy).
PsfModel sampled(const PsfModel& psf, double cx, double cy) {
  auto img = std::make_shared<PsfImage>();
  img->nx = img->ny = kPsfSize;
  img->pixels.resize(kPsfSize * kPsfSize);
  SimWorkspace ws;
  SimRenderer(psf, SimRenderer::Options{}).render_psf(kPsfSize, 1.0, cx, cy, true, img->pixels, ws);
  img->centre_x = 20, img->centre_y = 20;
  img->oversampling = 1;
  img->pixel_integrated = true;
  return PsfModel::Image(img);
}

std::unique_ptr<ExactRenderer> renderer_with(const PsfModel& psf) {
  RenderOptions ro;
  ro.stamp_size = kStamp;
  auto r = std::make_unique<ExactRenderer>(ro, ModelOptions{});
  std::string error;
  auto prepared = r->prepare_psf(psf, &error);
  if (!prepared) throw std::runtime_error(error);
  r->set_psf(prepared);
  return r;
}

ParamVector galaxy(double radius, double e1, double e2) {
  ParamVector p = ParameterSet::default_values();
  p[index(Param::kX0)] = 19.2, p[index(Param::kY0)] = 18.7;
  p[index(Param::kE1)] = e1, p[index(Param::kE2)] = e2, p[index(Param::kRadius)] = radius;
  p[index(Param::kBulgeA)] = 30, p[index(Param::kDiscA)] = 5;
  return p;
}

double worst_over_peak(const std::vector<double>& a, const std::vector<double>& b) {
  double peak = 0, worst = 0;
  for (std::size_t i = 0; i < a.size(); ++i) peak = std::max(peak, std::abs(b[i])), worst = std::max(worst, std::abs(a[i] - b[i]));
  return worst / peak;
}

TEST(ExactRendererImagePsf, SamplesOfAMoffatDrawWhatTheMoffatDraws) {
  std::vector<double> from_image(kStamp * kStamp), analytic(kStamp * kStamp);
  for (double fwhm : {2.85, 3.5, 4.5}) {
    const PsfModel psf = moffat(fwhm, 0.02, -0.04);
    auto image = renderer_with(sampled(psf, 20, 20)), exact = renderer_with(psf);
    double worst = 0;
    for (double r : {1.0, 2.0, 4.0}) {
      const ParamVector p = galaxy(r, 0.3, -0.2);
      ASSERT_EQ(image->render(p, from_image), RenderStatus::kOk);
      ASSERT_EQ(exact->render(p, analytic), RenderStatus::kOk);
      worst = std::max(worst, worst_over_peak(from_image, analytic));
    }
    std::printf("Moffat FWHM %.2f px from its samples: worst %.2e of the peak\n", fwhm, worst);
    // What the samples cannot hold: PSF x pixel power beyond the pixel Nyquist frequency, which
    // falls steeply with the FWHM (measured 3.1e-4, 5.6e-5, 7.6e-6).
    EXPECT_LT(worst, fwhm < 3 ? 5e-4 : fwhm < 4 ? 1e-4 : 2e-5) << fwhm;
  }
}

// Samples of the PSF centred half a pixel off the image's stated centre: the model moves by that.
TEST(ExactRendererImagePsf, AnOffCentreImageMovesTheModel) {
  const PsfModel psf = moffat(3.5, 0.0, 0.0);
  auto shifted = renderer_with(sampled(psf, 20.5, 19.75)), exact = renderer_with(psf);
  std::vector<double> a(kStamp * kStamp), b(kStamp * kStamp);
  ParamVector p = galaxy(2.0, 0.1, 0.2);
  ASSERT_EQ(shifted->render(p, a), RenderStatus::kOk);
  p[index(Param::kX0)] += 0.5, p[index(Param::kY0)] -= 0.25;
  ASSERT_EQ(exact->render(p, b), RenderStatus::kOk);
  EXPECT_LT(worst_over_peak(a, b), 2e-4);
}

TEST(ExactRendererImagePsf, JacobianMatchesFiniteDifferences) {
  auto r = renderer_with(sampled(moffat(3.5, 0.03, 0.01), 20.3, 19.9));
  const std::array<Param, 7> free = {Param::kX0, Param::kY0, Param::kE1, Param::kE2, Param::kRadius, Param::kBulgeA, Param::kDiscA};
  testing::expect_jacobian_matches_differences(*r, galaxy(2.2, 0.25, -0.1), free);
}

TEST(ExactRendererImagePsf, OversampledOrUnintegratedImagesAreRefusedWithAMessage) {
  PsfModel psf = sampled(moffat(3.5, 0, 0), 20, 20);
  auto img = std::make_shared<PsfImage>(*psf.image);
  img->oversampling = 2;
  RenderOptions ro;
  ro.stamp_size = kStamp;
  ExactRenderer r(ro, ModelOptions{});
  std::string error;
  EXPECT_FALSE(r.prepare_psf(PsfModel::Image(img), &error));
  EXPECT_NE(error.find("oversampling 1"), std::string::npos) << error;
}

}  // namespace
}  // namespace stampede
