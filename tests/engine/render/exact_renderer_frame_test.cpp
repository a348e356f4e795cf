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

// The same galaxy in the frame's pixels, worked out here from the real-space quadratic form
// (kernels/ellipse: q = N / ((1 - s) r^2), N = [[1 + s - 2 e1, -2 e2], [., 1 + s + 2 e1]], det q =
// r^-4), not through PixelFrame: Q_pix(dx) = Q_sky(J dx); centre x_ref + J^-1 u0; amplitudes so
// that A r^2 (the flux's scale) is kept.
ParamVector pixel_model(const ParamVector& sky, const PixelFrame& f) {
  const double e1 = sky[index(Param::kE1)], e2 = sky[index(Param::kE2)], r = sky[index(Param::kRadius)];
  const double s = e1 * e1 + e2 * e2, k = 1 / ((1 - s) * r * r);
  const double qxx = (1 + s - 2 * e1) * k, qxy = -2 * e2 * k, qyy = (1 + s + 2 * e1) * k;
  const double J[2][2] = {{f.dudx, f.dudy}, {f.dvdx, f.dvdy}};
  double P[2][2];  // J^T Q J
  const double Q[2][2] = {{qxx, qxy}, {qxy, qyy}};
  for (int i = 0; i < 2; ++i)
    for (int j = 0; j < 2; ++j) {
      P[i][j] = 0;
      for (int a = 0; a < 2; ++a)
        for (int b = 0; b < 2; ++b) P[i][j] += J[a][i] * Q[a][b] * J[b][j];
    }
  const double det = P[0][0] * P[1][1] - P[0][1] * P[0][1];
  const double rp = std::pow(det, -0.25);
  const double t = (P[0][0] + P[1][1]) * rp * rp / 2;  // (1 + s') / (1 - s')
  const double sp = (t - 1) / (t + 1);
  ParamVector p = sky;
  p[index(Param::kE1)] = (P[1][1] - P[0][0]) * rp * rp * (1 - sp) / 4;
  p[index(Param::kE2)] = -P[0][1] * rp * rp * (1 - sp) / 2;
  p[index(Param::kRadius)] = rp;
  const double jd = J[0][0] * J[1][1] - J[0][1] * J[1][0];
  const double u = sky[index(Param::kX0)], v = sky[index(Param::kY0)];
  p[index(Param::kX0)] = f.x_ref + (J[1][1] * u - J[0][1] * v) / jd;
  p[index(Param::kY0)] = f.y_ref + (-J[1][0] * u + J[0][0] * v) / jd;
  p[index(Param::kBulgeA)] *= r * r / (rp * rp);
  p[index(Param::kDiscA)] *= r * r / (rp * rp);
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
  const int npix = kStamp * kStamp;
  std::vector<double> model(npix), plus(npix), minus(npix);
  std::vector<std::vector<double>> jac(7, std::vector<double>(npix));
  std::array<double*, 7> cols;
  for (int k = 0; k < 7; ++k) cols[k] = jac[k].data();
  const ParamVector p = sky_model();
  ASSERT_EQ(renderer->render_with_jacobian(p, free, model, cols), RenderStatus::kOk);
  double peak = 0;
  for (double v : model) peak = std::max(peak, std::abs(v));
  for (int k = 0; k < 7; ++k) {
    const int i = index(free[k]);
    const double h = i <= 4 ? 1e-6 : 1e-4 * p[i];
    ParamVector pp = p, pm = p;
    pp[i] += h;
    pm[i] -= h;
    ASSERT_EQ(renderer->render(pp, plus), RenderStatus::kOk);
    ASSERT_EQ(renderer->render(pm, minus), RenderStatus::kOk);
    double max_fd = 0, max_diff = 0;
    for (int q = 0; q < npix; ++q) {
      const double fd = (plus[q] - minus[q]) / (2 * h);
      max_fd = std::max(max_fd, std::abs(fd));
      max_diff = std::max(max_diff, std::abs(fd - jac[k][q]));
    }
    EXPECT_GT(max_fd, 0) << param_name(free[k]);
    EXPECT_LE(max_diff, 1e-6 * max_fd + 2e-14 * peak / h) << param_name(free[k]);
  }
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
