// Tests engine/galaxy_model: the appendix-A reparameterisations (ellipticity mirror, radius
// softening) and their derivatives, and the parameter vector -> Sérsic blocks mapping, including
// the bulge offsets and the chain rule carried into dq/de.
#include "engine/model/galaxy_model.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <numbers>
#include <random>
#include <string>
#include <tuple>

#include "kernels/ellipse.hpp"
#include "kernels/sersic.hpp"

namespace stampede {
namespace {

constexpr double kMirror = 0.95;

// Largest absolute entry of a quadratic form, the scale for finite-difference tolerances.
double form_scale(const kernels::EllipseQuadratic& q) {
  return std::max({std::abs(q.xx), std::abs(q.xy), std::abs(q.yy)});
}

// ---------------------------------------------------------------------------------------------
// Ellipticity mirror.

TEST(MirrorEllipticity, IdentityInsideMirror) {
  for (double m : {0.0, 0.3, 0.7, 0.9499}) {
    for (double phi : {0.0, 0.9, -2.0, 3.0}) {
      const double e1 = m * std::cos(phi), e2 = m * std::sin(phi);
      const EffectiveEllipticity e = mirror_ellipticity(e1, e2, kMirror);
      EXPECT_EQ(e.e1, e1);
      EXPECT_EQ(e.e2, e2);
      EXPECT_EQ(e.d[0][0], 1.0);
      EXPECT_EQ(e.d[0][1], 0.0);
      EXPECT_EQ(e.d[1][0], 0.0);
      EXPECT_EQ(e.d[1][1], 1.0);
    }
  }
}

TEST(MirrorEllipticity, IdentityAtTheMirror) {
  // |e| = 0.95 itself: hypot may land an ulp either side, so equality to rounding (both branches
  // give e there, and the derivative's radial part is the only kink).
  for (double phi : {0.0, 0.9, -2.0, 3.0}) {
    const double e1 = kMirror * std::cos(phi), e2 = kMirror * std::sin(phi);
    const EffectiveEllipticity e = mirror_ellipticity(e1, e2, kMirror);
    EXPECT_NEAR(e.e1, e1, 1e-15);
    EXPECT_NEAR(e.e2, e2, 1e-15);
  }
}

TEST(MirrorEllipticity, TriangleWaveInModulus) {
  // |e| = 2.0: 0.95 -> 0 at 1.9, then -0.1: e_eff = -0.1 along the same direction.
  const double phi = 0.4;
  const EffectiveEllipticity e = mirror_ellipticity(2.0 * std::cos(phi), 2.0 * std::sin(phi), kMirror);
  EXPECT_NEAR(e.e1, -0.1 * std::cos(phi), 1e-14);
  EXPECT_NEAR(e.e2, -0.1 * std::sin(phi), 1e-14);
  // Reflection about 0.95: |e| = 1.2 -> 0.7, same sign.
  const EffectiveEllipticity f = mirror_ellipticity(1.2, 0.0, kMirror);
  EXPECT_NEAR(f.e1, 0.7, 1e-14);
  EXPECT_EQ(f.e2, 0.0);
  // Zero at 2 m = 1.9, -m at 3 m = 2.85, back to 0 at 3.8 (period 4 m).
  EXPECT_NEAR(mirror_ellipticity(0.0, 1.9, kMirror).e2, 0.0, 1e-14);
  EXPECT_NEAR(mirror_ellipticity(0.0, 2.85, kMirror).e2, -0.95, 1e-14);
  EXPECT_NEAR(mirror_ellipticity(0.0, 3.8, kMirror).e2, 0.0, 1e-14);
  EXPECT_NEAR(mirror_ellipticity(0.0, 4.0, kMirror).e2, 0.2, 1e-14);
}

TEST(MirrorEllipticity, ContinuousAcrossMirror) {
  for (double phi : {0.0, 1.0, -2.5}) {
    const double c = std::cos(phi), s = std::sin(phi);
    const EffectiveEllipticity below = mirror_ellipticity((kMirror - 1e-12) * c, (kMirror - 1e-12) * s, kMirror);
    const EffectiveEllipticity above = mirror_ellipticity((kMirror + 1e-12) * c, (kMirror + 1e-12) * s, kMirror);
    EXPECT_NEAR(below.e1, above.e1, 1e-11);
    EXPECT_NEAR(below.e2, above.e2, 1e-11);
    // And across the other kinks of the wave (|e| = 3 m), in value.
    const double t = 3 * kMirror;
    const EffectiveEllipticity b3 = mirror_ellipticity((t - 1e-12) * c, (t - 1e-12) * s, kMirror);
    const EffectiveEllipticity a3 = mirror_ellipticity((t + 1e-12) * c, (t + 1e-12) * s, kMirror);
    EXPECT_NEAR(b3.e1, a3.e1, 1e-11);
    EXPECT_NEAR(b3.e2, a3.e2, 1e-11);
  }
}

TEST(MirrorEllipticity, BoundedParallelAndDerivativeMatchesFiniteDifferences) {
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<double> mod(0.0, 3.0), angle(-std::numbers::pi, std::numbers::pi);
  // Piecewise e g(|e|) with g smooth between kinks: central differences with h = 1e-6 are exact up to
  // rounding eps / h ~ 1e-10 and h^2 g''' ~ 1e-12; 1e-8 absolute on O(1) entries.
  const double h = 1e-6;
  int checked = 0;
  for (int trial = 0; trial < 400; ++trial) {
    const double t = mod(rng), phi = angle(rng);
    const double e1 = t * std::cos(phi), e2 = t * std::sin(phi);
    const EffectiveEllipticity e = mirror_ellipticity(e1, e2, kMirror);
    EXPECT_LE(std::hypot(e.e1, e.e2), kMirror * (1 + 1e-15)) << "|e| = " << t;
    // Same direction (or opposite): the cross product vanishes.
    EXPECT_NEAR(e.e1 * e2 - e.e2 * e1, 0.0, 1e-14 * t);
    // Away from the kinks at |e| = m, 3 m, 5 m.
    bool near_kink = false;
    for (int k = 1; k <= 5; k += 2) near_kink |= std::abs(t - k * kMirror) < 1e-4;
    if (near_kink) continue;
    for (int j = 0; j < 2; ++j) {
      const double dj1 = j == 0 ? h : 0.0, dj2 = j == 1 ? h : 0.0;
      const EffectiveEllipticity p = mirror_ellipticity(e1 + dj1, e2 + dj2, kMirror);
      const EffectiveEllipticity m = mirror_ellipticity(e1 - dj1, e2 - dj2, kMirror);
      EXPECT_NEAR(e.d[0][j], (p.e1 - m.e1) / (2 * h), 1e-8) << "d e1_eff / d e" << j + 1 << " at |e| = " << t;
      EXPECT_NEAR(e.d[1][j], (p.e2 - m.e2) / (2 * h), 1e-8) << "d e2_eff / d e" << j + 1 << " at |e| = " << t;
    }
    ++checked;
  }
  EXPECT_GT(checked, 390);
}

TEST(MirrorEllipticity, FlipsSignBeyondTwiceTheMirror) {
  for (double t : {1.95, 2.2, 2.8}) {
    const EffectiveEllipticity e = mirror_ellipticity(t * 0.6, t * 0.8, kMirror);
    EXPECT_LT(e.e1 * 0.6 + e.e2 * 0.8, 0.0) << "|e| = " << t;
    EXPECT_NEAR(std::hypot(e.e1, e.e2), t - 2 * kMirror, 1e-14);  // s = 2 m - t on (m, 3 m]
  }
}

// ---------------------------------------------------------------------------------------------
// Radius softening.

TEST(SoftenRadius, ValuesAndDerivative) {
  const double R = 0.08;
  double d = 0;
  EXPECT_DOUBLE_EQ(soften_radius(0.0, R, &d), R / 2);
  EXPECT_EQ(d, 0.0);
  EXPECT_EQ(soften_radius(1.7, R, &d), 1.7);
  EXPECT_EQ(d, 1.0);
  EXPECT_EQ(soften_radius(-1.7, R, &d), 1.7);
  EXPECT_EQ(d, -1.0);
  // (R + r^2 / R) / 2 inside.
  EXPECT_DOUBLE_EQ(soften_radius(0.05, R, &d), 0.5 * (R + 0.05 * 0.05 / R));
  EXPECT_DOUBLE_EQ(d, 0.05 / R);
  // Never below R / 2.
  for (double r = -0.2; r <= 0.2; r += 0.001) EXPECT_GE(soften_radius(r, R, &d), R / 2 * (1 - 1e-15));
}

TEST(SoftenRadius, ContinuousWithContinuousDerivativeAtTransition) {
  const double R = 0.4;
  for (double sign : {1.0, -1.0}) {
    double d_in = 0, d_out = 0;
    const double in = soften_radius(sign * (R - 1e-12), R, &d_in);
    const double out = soften_radius(sign * (R + 1e-12), R, &d_out);
    EXPECT_NEAR(in, out, 1e-11);
    EXPECT_NEAR(in, R, 1e-11);
    EXPECT_NEAR(d_in, d_out, 1e-11);
    EXPECT_NEAR(d_in, sign, 1e-11);
  }
  // Derivative against central differences inside and outside (exact for the quadratic up to rounding).
  const double h = 1e-7;
  for (double r : {-0.9, -0.3, -0.05, 0.0, 0.1, 0.39, 0.41, 2.0}) {
    double d = 0, unused = 0;
    soften_radius(r, R, &d);
    const double fd = (soften_radius(r + h, R, &unused) - soften_radius(r - h, R, &unused)) / (2 * h);
    EXPECT_NEAR(d, fd, 1e-8) << "r = " << r;
  }
}

// ---------------------------------------------------------------------------------------------
// Model options.

TEST(ModelOptions, Validation) {
  std::string why;
  EXPECT_TRUE(ModelOptions{}.IsValid(&why));
  for (double m : {0.0, -0.5, 1.0, 1.5, static_cast<double>(NAN)}) {
    ModelOptions o;
    o.ellipticity_mirror = m;
    why.clear();
    EXPECT_FALSE(o.IsValid(&why)) << m;
    EXPECT_NE(why.find("ellipticity_mirror"), std::string::npos) << why;
  }
  for (double r : {0.0, -1.0, static_cast<double>(INFINITY), static_cast<double>(NAN)}) {
    ModelOptions o;
    o.radius_softening = r;
    why.clear();
    EXPECT_FALSE(o.IsValid(&why)) << r;
    EXPECT_NE(why.find("radius_softening"), std::string::npos) << why;
  }
  ModelOptions bad;
  bad.radius_softening = -1;
  EXPECT_FALSE(bad.IsValid(nullptr));
}

// ---------------------------------------------------------------------------------------------
// Components.

ParamVector default_params() {
  // Fixed parameters from the defaults (radius_ratio 1, n_b 4, n_d 1, delta_e 0, delta_theta 0); the
  // moment-derived ones (NaN start) set here.
  ParamVector p{};
  const auto spec = ParameterSet::defaults();
  for (int k = 0; k < kNumParams; ++k) p[k] = spec[k].start;
  p[index(Param::kX0)] = 10.0;
  p[index(Param::kY0)] = 10.0;
  p[index(Param::kE1)] = 0.2;
  p[index(Param::kE2)] = -0.1;
  p[index(Param::kRadius)] = 2.0;
  p[index(Param::kBulgeA)] = 100.0;
  p[index(Param::kDiscA)] = 10.0;
  return p;
}

constexpr double kStep = 0.2;  // sub-pixel size: upsampling 5

void expect_forms_equal(const kernels::EllipseQuadratic& a, const kernels::EllipseQuadratic& b, double tol,
                        const std::string& what) {
  EXPECT_NEAR(a.xx, b.xx, tol) << what;
  EXPECT_NEAR(a.xy, b.xy, tol) << what;
  EXPECT_NEAR(a.yy, b.yy, tol) << what;
}

TEST(GalaxyModel, DefaultParametersGiveBulgeAndDiscBlocks) {
  const ParamVector p = default_params();
  ASSERT_EQ(p[index(Param::kRadiusRatio)], 1.0);
  ASSERT_EQ(p[index(Param::kBulgeIndex)], 4.0);
  ASSERT_EQ(p[index(Param::kDiscIndex)], 1.0);
  ASSERT_EQ(p[index(Param::kDeltaE)], 0.0);
  ASSERT_EQ(p[index(Param::kDeltaTheta)], 0.0);
  const GalaxyModel model(ModelOptions{}, kStep);
  EXPECT_DOUBLE_EQ(model.softening_transition(), 0.4 * kStep);
  ModelComponents c;
  ASSERT_TRUE(model.components(p, &c));

  // Shapes: b_n, 1/2n, root, centre, quadratic form of (0.2, -0.1) at radius 2 for both.
  EXPECT_NEAR(c.bulge.shape.b, 7.669249, 1e-6);
  EXPECT_NEAR(c.disc.shape.b, 1.678347, 1e-6);
  EXPECT_EQ(c.bulge.shape.b, kernels::sersic_b(4.0));
  EXPECT_EQ(c.disc.shape.b, kernels::sersic_b(1.0));
  EXPECT_EQ(c.bulge.shape.inv_2n, 0.125);
  EXPECT_EQ(c.disc.shape.inv_2n, 0.5);
  EXPECT_EQ(c.bulge.shape.root, kernels::SersicRoot::kEighthRoot);
  EXPECT_EQ(c.disc.shape.root, kernels::SersicRoot::kSquareRoot);
  for (const kernels::SersicDerivativeBlock* b : {&c.bulge, &c.disc}) {
    EXPECT_EQ(b->shape.x0, 10.0);
    EXPECT_EQ(b->shape.y0, 10.0);
    expect_forms_equal(b->shape.q, kernels::ellipse_quadratic(0.2, -0.1, 2.0), 1e-15, "q");
    kernels::EllipseQuadratic d1, d2;
    kernels::ellipse_quadratic_derivatives(0.2, -0.1, 2.0, &d1, &d2);
    expect_forms_equal(b->dq_de1, d1, 1e-15, "dq/de1");
    expect_forms_equal(b->dq_de2, d2, 1e-15, "dq/de2");
    // radius 2 > the softening transition: r_eff = r, du/dr = -2 u / r.
    EXPECT_DOUBLE_EQ(b->du_dr_over_u, -1.0);
  }
  EXPECT_EQ(c.bulge.amplitude, 100.0);
  EXPECT_EQ(c.disc.amplitude, 10.0);
  EXPECT_EQ(c.bulge_radius, 2.0);
  EXPECT_EQ(c.disc_radius, 2.0);
  EXPECT_EQ(c.e1, 0.2);
  EXPECT_EQ(c.e2, -0.1);

  double fb = 0, fd = 0;
  model.fluxes(p, &fb, &fd);
  EXPECT_DOUBLE_EQ(fb, kernels::sersic_flux(100.0, 2.0, 4.0));
  EXPECT_DOUBLE_EQ(fd, kernels::sersic_flux(10.0, 2.0, 1.0));
}

TEST(GalaxyModel, RadiusRatioAndSoftening) {
  const GalaxyModel model(ModelOptions{}, kStep);
  const double R = model.softening_transition();
  ParamVector p = default_params();
  p[index(Param::kRadiusRatio)] = 0.5;
  p[index(Param::kRadius)] = 0.5 * R;  // inside the softening: r_eff = (R + r^2/R) / 2
  ModelComponents c;
  ASSERT_TRUE(model.components(p, &c));
  const double r_eff = 0.5 * (R + 0.25 * R);
  EXPECT_DOUBLE_EQ(c.disc_radius, r_eff);
  EXPECT_DOUBLE_EQ(c.bulge_radius, 0.5 * r_eff);
  expect_forms_equal(c.bulge.shape.q, kernels::ellipse_quadratic(0.2, -0.1, 0.5 * r_eff), 1e-12 * form_scale(c.bulge.shape.q),
                     "bulge q");
  // du/dr through the softening, checked against finite differences of q (q proportional to 1/r_eff^2).
  // h = 1e-7 on r_eff ~ 0.05 px: truncation (h / r)^2 ~ 1e-11 and rounding eps q / (h fd) ~ 1e-10
  // relative; 1e-7 relative.
  const double h = 1e-7;
  ParamVector pp = p, pm = p;
  pp[index(Param::kRadius)] += h;
  pm[index(Param::kRadius)] -= h;
  ModelComponents cp, cm;
  ASSERT_TRUE(model.components(pp, &cp));
  ASSERT_TRUE(model.components(pm, &cm));
  for (const auto& [block, plus, minus] : {std::tuple{&c.bulge, &cp.bulge, &cm.bulge}, std::tuple{&c.disc, &cp.disc, &cm.disc}}) {
    const double fd = (plus->shape.q.xx - minus->shape.q.xx) / (2 * h);
    EXPECT_NEAR(block->du_dr_over_u * block->shape.q.xx, fd, 1e-7 * std::abs(fd));
  }
  double fb = 0, fd = 0;
  model.fluxes(p, &fb, &fd);
  EXPECT_DOUBLE_EQ(fb, kernels::sersic_flux(100.0, 0.5 * r_eff, 4.0));
  EXPECT_DOUBLE_EQ(fd, kernels::sersic_flux(10.0, r_eff, 1.0));
}

TEST(GalaxyModel, RejectsNonFiniteParametersAndInvalidBulge) {
  const GalaxyModel model(ModelOptions{}, kStep);
  ModelComponents c;
  for (int k = 0; k < kNumParams; ++k) {
    for (double bad : {static_cast<double>(NAN), static_cast<double>(INFINITY), -static_cast<double>(INFINITY)}) {
      ParamVector p = default_params();
      p[k] = bad;
      EXPECT_FALSE(model.components(p, &c)) << param_name(static_cast<Param>(k)) << " = " << bad;
    }
  }
  // |e_bulge| = 0.9 + 0.2 >= 1: no valid bulge.
  ParamVector p = default_params();
  p[index(Param::kE1)] = 0.9;
  p[index(Param::kE2)] = 0.0;
  p[index(Param::kDeltaE)] = 0.2;
  EXPECT_FALSE(model.components(p, &c));
  p[index(Param::kDeltaE)] = 0.05;
  EXPECT_TRUE(model.components(p, &c));
  // A non-positive radius ratio gives no bulge radius.
  p = default_params();
  p[index(Param::kRadiusRatio)] = 0.0;
  EXPECT_FALSE(model.components(p, &c));
}

// Position angle of an ellipticity, radians.
double angle_of(double e1, double e2) { return 0.5 * std::atan2(e2, e1); }

// Bulge ellipticity from its quadratic form: q = N / ((1 - |e|^2) r^2) with N_yy - N_xx = 4 e1,
// N_xy = -2 e2, N_xx + N_yy = 2 (1 + |e|^2); solve for e given q and r.
void ellipticity_of_form(const kernels::EllipseQuadratic& q, double r, double* e1, double* e2) {
  const double r2 = r * r;
  const double t = (q.xx + q.yy) * r2 / 2;  // (1 + s) / (1 - s)
  const double s = (t - 1) / (t + 1);
  *e1 = (q.yy - q.xx) * r2 * (1 - s) / 4;
  *e2 = -q.xy * r2 * (1 - s) / 2;
}

TEST(GalaxyModel, BulgeOffsetsRotateAndStretchEllipticity) {
  const GalaxyModel model(ModelOptions{}, kStep);
  ParamVector p = default_params();
  p[index(Param::kDeltaE)] = 0.1;
  p[index(Param::kDeltaTheta)] = 0.3;
  ModelComponents c;
  ASSERT_TRUE(model.components(p, &c));
  double b1 = 0, b2 = 0;
  ellipticity_of_form(c.bulge.shape.q, c.bulge_radius, &b1, &b2);
  const double mod = std::hypot(0.2, -0.1);
  // Round trip through the form: ~1e-14.
  EXPECT_NEAR(std::hypot(b1, b2), mod + 0.1, 1e-13);
  EXPECT_NEAR(angle_of(b1, b2) - angle_of(0.2, -0.1), 0.3, 1e-13);
  // The disc is untouched.
  expect_forms_equal(c.disc.shape.q, kernels::ellipse_quadratic(0.2, -0.1, 2.0), 1e-15, "disc q");
  // Same effective e reported (the disc's).
  EXPECT_EQ(c.e1, 0.2);
  EXPECT_EQ(c.e2, -0.1);
}

// dq/de1, dq/de2 of both blocks against central differences of their q with respect to the
// *model* e1, e2 (through the mirror and the bulge offsets).
void check_chain(const GalaxyModel& model, const ParamVector& p, const std::string& label) {
  ModelComponents c;
  ASSERT_TRUE(model.components(p, &c)) << label;
  // q is smooth in e away from the mirror kinks; h = 1e-6 gives truncation ~h^2 q''' and rounding
  // ~eps q / h, both < 1e-9 of the entries; 1e-7 of the form's largest entry.
  const double h = 1e-6;
  for (int j = 0; j < 2; ++j) {
    const Param which = j == 0 ? Param::kE1 : Param::kE2;
    ParamVector pp = p, pm = p;
    pp[index(which)] += h;
    pm[index(which)] -= h;
    ModelComponents cp, cm;
    ASSERT_TRUE(model.components(pp, &cp));
    ASSERT_TRUE(model.components(pm, &cm));
    auto fd = [&](const kernels::EllipseQuadratic& a, const kernels::EllipseQuadratic& b) {
      return kernels::EllipseQuadratic{(a.xx - b.xx) / (2 * h), (a.xy - b.xy) / (2 * h), (a.yy - b.yy) / (2 * h)};
    };
    const kernels::EllipseQuadratic fd_bulge = fd(cp.bulge.shape.q, cm.bulge.shape.q);
    const kernels::EllipseQuadratic fd_disc = fd(cp.disc.shape.q, cm.disc.shape.q);
    const kernels::EllipseQuadratic& an_bulge = j == 0 ? c.bulge.dq_de1 : c.bulge.dq_de2;
    const kernels::EllipseQuadratic& an_disc = j == 0 ? c.disc.dq_de1 : c.disc.dq_de2;
    const std::string what = label + (j == 0 ? " d/de1" : " d/de2");
    expect_forms_equal(an_bulge, fd_bulge, 1e-7 * form_scale(fd_bulge) + 1e-12, what + " bulge");
    expect_forms_equal(an_disc, fd_disc, 1e-7 * form_scale(fd_disc) + 1e-12, what + " disc");
  }
}

TEST(GalaxyModel, ChainedEllipticityDerivativesMatchFiniteDifferences) {
  const GalaxyModel model(ModelOptions{}, kStep);
  ParamVector p = default_params();
  p[index(Param::kDeltaE)] = 0.1;
  p[index(Param::kDeltaTheta)] = 0.3;
  check_chain(model, p, "e = (0.2, -0.1), delta = (0.1, 0.3)");
  // Mirrored disc ellipticity (|e| = 1.3 -> 0.6) with bulge offsets on top.
  p[index(Param::kE1)] = 1.2;
  p[index(Param::kE2)] = 0.5;
  check_chain(model, p, "e = (1.2, 0.5), delta = (0.1, 0.3)");
  // Negative offsets, other quadrant, beyond 2 m (sign flip).
  p[index(Param::kE1)] = -1.7;
  p[index(Param::kE2)] = -1.1;
  p[index(Param::kDeltaE)] = -0.05;
  p[index(Param::kDeltaTheta)] = -1.0;
  check_chain(model, p, "e = (-1.7, -1.1), delta = (-0.05, -1.0)");
  // No offsets, mirrored.
  p = default_params();
  p[index(Param::kE1)] = 0.3;
  p[index(Param::kE2)] = 1.0;
  check_chain(model, p, "e = (0.3, 1.0), no offsets");
}

}  // namespace
}  // namespace stampede
