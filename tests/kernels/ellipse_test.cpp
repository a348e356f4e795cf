// Tests kernels/ellipse: the elliptical-radius quadratic form against the geometry it encodes
// (semi-axes along the position angle, area preservation) and its analytic e-derivatives.
#include "kernels/ellipse.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <numbers>
#include <random>

namespace stampede::kernels {
namespace {

constexpr double kPi = std::numbers::pi;

struct Case {
  double mod_e, theta, r;
};

// |e| from 0 to 0.95, position angles in all quadrants, radii from sub-pixel to large.
constexpr Case kCases[] = {
    {0.0, 0.3, 1.0},  {0.1, 0.0, 2.0},   {0.3, 0.4, 0.5},   {0.5, kPi / 2, 3.0}, {0.7, -1.1, 1.7},
    {0.9, 2.5, 0.8},  {0.95, 1.0, 10.0}, {0.25, kPi, 1.3},  {0.6, -kPi / 4, 0.37},
};

TEST(EllipseQuadratic, SemiAxesLieOnUnitContour) {
  // u is a sum of three products of O(1/r^2) terms: 1e-12 relative is a few hundred ulp.
  for (const Case& c : kCases) {
    const double e1 = c.mod_e * std::cos(2 * c.theta), e2 = c.mod_e * std::sin(2 * c.theta);
    const EllipseQuadratic q = ellipse_quadratic(e1, e2, c.r);
    const double a = c.r * std::sqrt((1 + c.mod_e) / (1 - c.mod_e));
    const double b = c.r * std::sqrt((1 - c.mod_e) / (1 + c.mod_e));
    const double ax = a * std::cos(c.theta), ay = a * std::sin(c.theta);                  // major axis
    const double bx = -b * std::sin(c.theta), by = b * std::cos(c.theta);                 // minor axis
    EXPECT_NEAR(q(ax, ay), 1.0, 1e-12) << "|e| = " << c.mod_e << " theta = " << c.theta;
    EXPECT_NEAR(q(-ax, -ay), 1.0, 1e-12);
    EXPECT_NEAR(q(bx, by), 1.0, 1e-12) << "|e| = " << c.mod_e << " theta = " << c.theta;
    // The two axes are conjugate (principal) directions: u(va + vb) = u(va) + u(vb) = 2. Without
    // this, a form with the right values on both axes but rotated principal axes would pass.
    EXPECT_NEAR(q(ax + bx, ay + by), 2.0, 1e-12);
    EXPECT_NEAR(q(ax - bx, ay - by), 2.0, 1e-12);
    // Circularised radius sqrt(a b) = r.
    EXPECT_NEAR(std::sqrt(a * b), c.r, 1e-12 * c.r);
  }
}

TEST(EllipseQuadratic, MajorAxisIsTheLongOne) {
  // e1 > 0 elongates along x, e2 > 0 along y = x (data README): u grows more slowly that way.
  const EllipseQuadratic q1 = ellipse_quadratic(0.4, 0.0, 1.0);
  EXPECT_LT(q1(1.0, 0.0), q1(0.0, 1.0));
  const EllipseQuadratic q2 = ellipse_quadratic(0.0, 0.4, 1.0);
  EXPECT_LT(q2(1.0, 1.0), q2(1.0, -1.0));
  const EllipseQuadratic q3 = ellipse_quadratic(-0.4, 0.0, 1.0);
  EXPECT_GT(q3(1.0, 0.0), q3(0.0, 1.0));
}

TEST(EllipseQuadratic, PreservesArea) {
  // det = xx yy - xy^2 = 1 / r^4 (the ellipse u <= 1 has area pi r^2 for every e).
  for (const Case& c : kCases) {
    const double e1 = c.mod_e * std::cos(2 * c.theta), e2 = c.mod_e * std::sin(2 * c.theta);
    const EllipseQuadratic q = ellipse_quadratic(e1, e2, c.r);
    const double det = q.xx * q.yy - q.xy * q.xy;
    // The determinant cancels (1+|e|^2)^2 - 4|e|^2 = (1-|e|^2)^2: relative error grows like
    // eps / (1-|e|^2)^2 ~ 1e-13 at |e| = 0.95, so 1e-11 relative.
    EXPECT_NEAR(det * std::pow(c.r, 4), 1.0, 1e-11) << "|e| = " << c.mod_e;
    EXPECT_GT(q.xx, 0.0);
    EXPECT_GT(q.yy, 0.0);
  }
}

TEST(EllipseQuadratic, ZeroEllipticityIsCircle) {
  for (double r : {0.3, 1.0, 4.5}) {
    const EllipseQuadratic q = ellipse_quadratic(0.0, 0.0, r);
    EXPECT_DOUBLE_EQ(q.xx, 1.0 / (r * r));
    EXPECT_DOUBLE_EQ(q.yy, 1.0 / (r * r));
    EXPECT_EQ(q.xy, 0.0);
    EXPECT_NEAR(q(r * std::cos(0.7), r * std::sin(0.7)), 1.0, 1e-14);
  }
}

TEST(EllipseQuadratic, OperatorEvaluatesTheForm) {
  const EllipseQuadratic q{1.5, -0.25, 0.75};
  EXPECT_DOUBLE_EQ(q(2.0, -3.0), 1.5 * 4.0 + 2.0 * -0.25 * 2.0 * -3.0 + 0.75 * 9.0);
}

TEST(EllipseQuadraticDerivatives, MatchCentralFiniteDifferences) {
  std::mt19937_64 rng(20240611);
  std::uniform_real_distribution<double> mod(0.0, 0.9), angle(-kPi, kPi), radius(0.3, 5.0);
  // Step 1e-6: truncation h^2 q''' / 6 and rounding eps q / h are both ~1e-10 of the derivative even
  // at |e| = 0.9 where 1/(1-|e|^2) ~ 5 amplifies the higher derivatives; 1e-7 relative leaves margin.
  const double h = 1e-6;
  for (int trial = 0; trial < 40; ++trial) {
    const double m = trial == 0 ? 0.9 : (trial == 1 ? 0.0 : mod(rng));
    const double phi = angle(rng), r = radius(rng);
    const double e1 = m * std::cos(phi), e2 = m * std::sin(phi);
    EllipseQuadratic d1, d2;
    ellipse_quadratic_derivatives(e1, e2, r, &d1, &d2);
    const EllipseQuadratic p1 = ellipse_quadratic(e1 + h, e2, r), m1 = ellipse_quadratic(e1 - h, e2, r);
    const EllipseQuadratic p2 = ellipse_quadratic(e1, e2 + h, r), m2 = ellipse_quadratic(e1, e2 - h, r);
    const EllipseQuadratic fd1{(p1.xx - m1.xx) / (2 * h), (p1.xy - m1.xy) / (2 * h), (p1.yy - m1.yy) / (2 * h)};
    const EllipseQuadratic fd2{(p2.xx - m2.xx) / (2 * h), (p2.xy - m2.xy) / (2 * h), (p2.yy - m2.yy) / (2 * h)};
    // An entry can vanish (e.g. d xy / d e1 is proportional to e1 e2): the floor is relative to the
    // largest entry of the same derivative form, which sets the rounding error of the differences.
    auto check = [&](const EllipseQuadratic& analytic, const EllipseQuadratic& fd, const char* which) {
      const double scale = std::max({std::abs(fd.xx), std::abs(fd.xy), std::abs(fd.yy)});
      EXPECT_NEAR(analytic.xx, fd.xx, 1e-7 * scale) << which << " xx, e = (" << e1 << ", " << e2 << "), r = " << r;
      EXPECT_NEAR(analytic.xy, fd.xy, 1e-7 * scale) << which << " xy, e = (" << e1 << ", " << e2 << "), r = " << r;
      EXPECT_NEAR(analytic.yy, fd.yy, 1e-7 * scale) << which << " yy, e = (" << e1 << ", " << e2 << "), r = " << r;
    };
    check(d1, fd1, "d/de1");
    check(d2, fd2, "d/de2");
  }
}

TEST(EllipseQuadraticDerivatives, ClosedFormAtZeroEllipticity) {
  // At e = 0: xx = (1 - 2 e1)/r^2 + O(e^2), xy = -2 e2 / r^2, yy = (1 + 2 e1)/r^2.
  EllipseQuadratic d1, d2;
  ellipse_quadratic_derivatives(0.0, 0.0, 2.0, &d1, &d2);
  EXPECT_DOUBLE_EQ(d1.xx, -0.5);
  EXPECT_DOUBLE_EQ(d1.xy, 0.0);
  EXPECT_DOUBLE_EQ(d1.yy, 0.5);
  EXPECT_DOUBLE_EQ(d2.xx, 0.0);
  EXPECT_DOUBLE_EQ(d2.xy, -0.5);
  EXPECT_DOUBLE_EQ(d2.yy, 0.0);
}


// ellipse_parameters inverts ellipse_quadratic, and refuses forms that are no ellipse.
TEST(EllipseParameters, InvertEllipseQuadratic) {
  for (double e1 : {-0.7, -0.2, 0.0, 0.35, 0.9})
    for (double e2 : {-0.3, 0.0, 0.25})
      for (double r : {0.05, 1.0, 37.0}) {
        if (e1 * e1 + e2 * e2 >= 0.95) continue;
        double a = 0, b = 0, c = 0;
        ASSERT_TRUE(ellipse_parameters(ellipse_quadratic(e1, e2, r), &a, &b, &c));
        EXPECT_NEAR(a, e1, 1e-12);
        EXPECT_NEAR(b, e2, 1e-12);
        EXPECT_NEAR(c, r, 1e-12 * r);
      }
  double a, b, c;
  EXPECT_FALSE(ellipse_parameters({1.0, 2.0, 1.0}, &a, &b, &c));   // indefinite
  EXPECT_FALSE(ellipse_parameters({-1.0, 0.0, -1.0}, &a, &b, &c));  // negative definite
}

}  // namespace
}  // namespace stampede::kernels
