// Tests for the exact renderer in a pixel frame (engine/model/pixel_frame, ExactRenderer::set_frame):
// a model in (u, v) arcsec seen through a cutout's WCS Jacobian is the same profile drawn in that
// cutout's pixels with its shape carried over independently here; d/du0, d/dv0 and the shape
// derivatives agree with finite differences; the identity frame changes nothing.
#include <gtest/gtest.h>

#include <cmath>
#include <memory>
#include <random>
#include <vector>

#include "engine/model/pixel_frame.hpp"
#include "engine/render/exact_renderer.hpp"
#include "support/jacobian_check.hpp"
#include "support/sky_to_pixel.hpp"

namespace stampede {
namespace {

constexpr int kStamp = 33;

std::unique_ptr<ExactRenderer> make_renderer() {
  RenderOptions ro;
  ro.stamp_size = kStamp;
  auto r = std::make_unique<ExactRenderer>(ro, ModelOptions{});
  PsfModel psf;
  psf.kind = PsfKind::kMoffat;
  psf.moffat = {3.0, 3.4, 0.02, -0.03, 0.0};
  std::string error;
  auto prepared = r->prepare_psf(psf, &error);
  if (!prepared) throw std::runtime_error(error);
  r->set_psf(prepared);
  return r;
}

// A DES-like epoch: 0.263"/pixel, rotated by `angle`, a few per cent of scale and shear, the
// object near the middle of the cutout.
PixelFrame frame(double angle, double scale, double shear, double x_ref, double y_ref) {
  const double c = std::cos(angle), s = std::sin(angle), a = 0.263 * scale;
  // J = a R(angle) (1 + shear along x)
  PixelFrame f;
  f.dudx = a * (c * (1 + shear)), f.dudy = a * (-s * (1 - shear));
  f.dvdx = a * (s * (1 + shear)), f.dvdy = a * (c * (1 - shear));
  f.x_ref = x_ref, f.y_ref = y_ref;
  return f;
}

ParamVector sky_model() {
  ParamVector p = ParameterSet::default_values();
  p[index(Param::kX0)] = 0.11;  // arcsec
  p[index(Param::kY0)] = -0.07;
  p[index(Param::kE1)] = 0.31;
  p[index(Param::kE2)] = -0.17;
  p[index(Param::kRadius)] = 0.62;  // arcsec
  p[index(Param::kBulgeA)] = 300;   // per arcsec^2
  p[index(Param::kDiscA)] = 40;
  return p;
}

// The same galaxy in the frame's pixels (tests/support/sky_to_pixel.hpp, derived independently of
// PixelFrame), with amplitudes that keep A r^2, the flux's scale.
ParamVector pixel_model(const ParamVector& sky, const PixelFrame& f) {
  const double r = sky[index(Param::kRadius)];
  const testing::PixelEllipse e = testing::sky_to_pixel(sky[index(Param::kE1)], sky[index(Param::kE2)], r,
                                                        sky[index(Param::kX0)], sky[index(Param::kY0)], f);
  ParamVector p = sky;
  p[index(Param::kE1)] = e.e1;
  p[index(Param::kE2)] = e.e2;
  p[index(Param::kRadius)] = e.radius;
  p[index(Param::kX0)] = e.x;
  p[index(Param::kY0)] = e.y;
  p[index(Param::kBulgeA)] *= r * r / (e.radius * e.radius);
  p[index(Param::kDiscA)] *= r * r / (e.radius * e.radius);
  return p;
}

TEST(ExactRendererFrame, ASkyModelIsThePixelModelItMapsTo) {
  auto renderer = make_renderer();
  std::vector<double> framed(kStamp * kStamp), pixels(kStamp * kStamp);
  const ParamVector sky = sky_model();
  for (double angle : {0.0, 0.4, M_PI / 2, 2.2, -1.0}) {
    const PixelFrame f = frame(angle, 1.02, 0.015, 16.3, 15.8);
    renderer->set_frame(f);
    ASSERT_EQ(renderer->render(sky, framed), RenderStatus::kOk);
    renderer->set_frame(PixelFrame());
    ASSERT_EQ(renderer->render(pixel_model(sky, f), pixels), RenderStatus::kOk);
    double peak = 0, worst = 0, sum = 0;
    for (int i = 0; i < kStamp * kStamp; ++i) {
      peak = std::max(peak, std::abs(pixels[i]));
      worst = std::max(worst, std::abs(framed[i] - pixels[i]));
      sum += framed[i];
    }
    // Not bitwise: the two draws sum their terms in other orders, and the wrap correction picks its
    // copies from a threshold on each one's peak estimate (the copies it leaves are < 1e-8 of it).
    EXPECT_LT(worst, 1e-9 * peak) << "angle " << angle;
    EXPECT_GT(sum, 0.5 * peak);
  }
}

TEST(ExactRendererFrame, JacobianMatchesFiniteDifferences) {
  auto renderer = make_renderer();
  renderer->set_frame(frame(0.7, 0.97, -0.02, 17.2, 15.1));
  const std::array<Param, 7> free = {Param::kX0, Param::kY0, Param::kE1, Param::kE2, Param::kRadius, Param::kBulgeA, Param::kDiscA};
  testing::expect_jacobian_matches_differences(*renderer, sky_model(), free);
}

TEST(ExactRendererFrame, TheIdentityFrameChangesNothing) {
  auto renderer = make_renderer();
  ParamVector p = sky_model();
  p[index(Param::kX0)] = 16.2, p[index(Param::kY0)] = 15.9, p[index(Param::kRadius)] = 2.1;
  std::vector<double> before(kStamp * kStamp), after(kStamp * kStamp);
  ASSERT_EQ(renderer->render(p, before), RenderStatus::kOk);
  renderer->set_frame(frame(0.3, 1, 0, 1, 1));
  renderer->set_frame(PixelFrame());
  ASSERT_EQ(renderer->render(p, after), RenderStatus::kOk);
  EXPECT_EQ(before, after);
}

}  // namespace
}  // namespace stampede
