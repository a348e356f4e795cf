// The cubic splines of the noise-bias calibration: exact on parabolas (three nodes) and cubics
// (more), at the nodes and on functions linear in each coordinate, close to a smooth function
// between nodes, and well defined on grids of one or two nodes and on dense ones.
#include "kernels/tensor_spline.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <vector>

namespace stampede::kernels {
namespace {

double spline1(const std::vector<double>& nodes, const std::vector<double>& y, double x) {
  const SplineWeights s(nodes);
  EXPECT_TRUE(s.ok());
  std::vector<double> w(nodes.size());
  s.at(x, w);
  double v = 0;
  for (std::size_t k = 0; k < y.size(); ++k) v += w[k] * y[k];
  return v;
}

// Three nodes give the parabola through them: 0, 1, 0 at 0, 1, 2 is 1 - (x - 1)^2.
TEST(SplineWeights, ThreeNodesAreTheirParabola) {
  const std::vector<double> nodes = {0, 1, 2}, y = {0, 1, 0};
  for (double x : {0.0, 0.25, 0.5, 1.3, 2.0}) EXPECT_NEAR(spline1(nodes, y, x), 1 - (x - 1) * (x - 1), 1e-15) << x;
  const std::vector<double> uneven = {0.2, 0.5, 1.7};
  const auto q = [](double x) { return 3 - 2 * x + 5 * x * x; };
  for (double x : {0.2, 0.3, 0.9, 1.7}) EXPECT_NEAR(spline1(uneven, {q(0.2), q(0.5), q(1.7)}, x), q(x), 1e-13) << x;
}

// Not-a-knot ends: any cubic is reproduced on any nodes; slopes and curvature continuous at the
// inner nodes for other data.
TEST(SplineWeights, ReproducesCubicsAndIsSmoothAtItsNodes) {
  const std::vector<double> nodes = {0, 0.3, 1.1, 1.5, 3};
  const auto cubic = [](double x) { return 1 - 2 * x + 0.7 * x * x - 0.4 * x * x * x; };
  std::vector<double> y;
  for (double x : nodes) y.push_back(cubic(x));
  for (double x = 0; x <= 3; x += 0.07) EXPECT_NEAR(spline1(nodes, y, x), cubic(x), 1e-12) << x;
  const std::vector<double> v = {1, -2, 0.5, 4, 3};
  const double h = 1e-4;
  for (double knot : {0.3, 1.1, 1.5}) {
    const double s0 = spline1(nodes, v, knot), left = spline1(nodes, v, knot - h), right = spline1(nodes, v, knot + h);
    EXPECT_NEAR((s0 - left) / h, (right - s0) / h, 2e-3 * 50) << knot;  // slopes differ by O(h M)
    const double left2 = spline1(nodes, v, knot - 2 * h), right2 = spline1(nodes, v, knot + 2 * h);
    EXPECT_NEAR((s0 - 2 * left + left2) / (h * h), (right2 - 2 * right + s0) / (h * h), 0.1) << knot;
  }
}

TEST(SplineWeights, OneNodeIsAConstantAndTwoALine) {
  EXPECT_DOUBLE_EQ(spline1({2.0}, {7.0}, -5.0), 7.0);
  EXPECT_DOUBLE_EQ(spline1({2.0}, {7.0}, 2.5), 7.0);
  EXPECT_NEAR(spline1({1.0, 3.0}, {2.0, 6.0}, 2.5), 5.0, 1e-15);
}

TEST(SplineWeights, BadNodesAreRefused) {
  EXPECT_FALSE(SplineWeights(std::vector<double>{}).ok());
  EXPECT_FALSE(SplineWeights(std::vector<double>{1, 1}).ok());
  EXPECT_FALSE(SplineWeights(std::vector<double>{2, 1}).ok());
  EXPECT_FALSE(SplineWeights(std::vector<double>{0, NAN}).ok());
  std::vector<double> many(kMaxSplineNodes + 1);
  for (std::size_t i = 0; i < many.size(); ++i) many[i] = static_cast<double>(i);
  EXPECT_FALSE(SplineWeights(many).ok());
  many.pop_back();
  EXPECT_TRUE(SplineWeights(many).ok());
}

// A smooth stand-in for a bias coefficient over (disc radius, bulge fraction).
double smooth(double r, double f) { return 0.02 / (r * r) * (1 + 0.5 * f) - 0.003 * f * f; }

TensorSpline on_grid(const std::vector<double>& rs, const std::vector<double>& fs,
                     double (*fn)(double, double)) {
  std::vector<double> lr, values;
  for (double r : rs) lr.push_back(std::log(r));
  for (double r : rs)
    for (double f : fs) values.insert(values.end(), {fn(r, f), -2 * fn(r, f)});
  return TensorSpline(lr, fs, values, 2);
}

TEST(TensorSpline, ReproducesNodesAndFunctionsLinearInEachCoordinate) {
  const std::vector<double> rs = {1.2, 1.6, 2.1, 2.8}, fs = {0, 0.5, 1};
  const auto bilinear = [](double r, double f) { return 0.3 - 0.1 * std::log(r) + 0.05 * f - 0.2 * std::log(r) * f; };
  const TensorSpline s = on_grid(rs, fs, +bilinear);
  ASSERT_TRUE(s.ok());
  double out[2];
  for (double r : {1.2, 1.3, 1.6, 1.9, 2.8})
    for (double f : {0.0, 0.2, 0.5, 0.77, 1.0}) {
      s.evaluate(std::log(r), f, out);
      EXPECT_NEAR(out[0], bilinear(r, f), 1e-14) << r << " " << f;
      EXPECT_NEAR(out[1], -2 * bilinear(r, f), 1e-14);
    }
  const TensorSpline t = on_grid(rs, fs, smooth);
  for (double r : rs)
    for (double f : fs) {
      t.evaluate(std::log(r), f, out);
      EXPECT_NEAR(out[0], smooth(r, f), 1e-15);
    }
}

// Bias coefficients fall roughly as 1/r^2: interpolated in (ln r, F) as the calibration does, on
// the paper's 3 x 3 grid, a 7 x 5 one and a dense 8 x 5 one (where a Gaussian RBF of fixed width
// is singular).
TEST(TensorSpline, FollowsASmoothFunctionBetweenNodes) {
  struct Case {
    std::vector<double> rs, fs;
    double tolerance;  // of the function's largest value
  };
  // Stated tolerances, about 1.5x the worst errors measured.
  const Case cases[] = {{{1.0, 2.5, 5.0}, {0, 0.5, 1}, 0.15},
                        {{1.0, 1.5, 2.0, 2.5, 3.0, 4.0, 5.0}, {0, 0.25, 0.5, 0.75, 1}, 7e-3},
                        {{1.2, 1.4, 1.6, 1.85, 2.1, 2.45, 2.8, 3.2}, {0, 0.25, 0.5, 0.75, 1}, 3e-4}};
  for (const Case& c : cases) {
    const TensorSpline s = on_grid(c.rs, c.fs, smooth);
    ASSERT_TRUE(s.ok());
    double worst = 0, peak = 0, out[2];
    for (double r = c.rs.front(); r <= c.rs.back(); r += 0.037)
      for (double f = 0; f <= 1; f += 0.043) {
        s.evaluate(std::log(r), f, out);
        worst = std::max(worst, std::abs(out[0] - smooth(r, f)));
        peak = std::max(peak, std::abs(smooth(r, f)));
      }
    std::printf("%zu x %zu grid: worst |spline - f| %.2e of the largest |f|\n", c.rs.size(), c.fs.size(), worst / peak);
    EXPECT_LT(worst, c.tolerance * peak);
  }
}

TEST(TensorSpline, InconsistentInputIsRefused) {
  const std::vector<double> x = {0, 1}, y = {0, 1}, values(4 * 3, 1.0);
  EXPECT_TRUE(TensorSpline(x, y, values, 3).ok());
  EXPECT_FALSE(TensorSpline(x, y, values, 2).ok());
  EXPECT_FALSE(TensorSpline(std::vector<double>{1, 0}, y, values, 3).ok());
  double out[2] = {0, 0};
  TensorSpline(x, y, values, 2).evaluate(0, 0, out);  // not ok: NaN, never a number
  EXPECT_TRUE(std::isnan(out[0]) && std::isnan(out[1]));
}

}  // namespace
}  // namespace stampede::kernels
