// The linear amplitudes of variable projection against a direct weighted least-squares solve,
// the W-orthogonality that makes the projected gradient exact, and a degenerate pair.
#include "engine/solver/variable_projection.hpp"

#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <cmath>
#include <random>
#include <vector>

namespace stampede {
namespace {

struct Pair {
  std::vector<double> w, phi0, phi1, d;
  LinearAmplitudes la;
  bool ok = false;
};

Pair make_pair(int n, double dependence, std::mt19937& rng) {
  std::uniform_real_distribution<double> u(0.0, 1.0);
  Pair p;
  for (int i = 0; i < n; ++i) {
    p.w.push_back(i % 7 == 3 ? 0.0 : 0.5 + u(rng));  // some masked pixels
    p.phi0.push_back(std::exp(-0.01 * i) + 0.1 * u(rng));
    p.phi1.push_back(dependence * p.phi0.back() + (dependence == 0 ? std::exp(-0.03 * i) : 0.0));
    p.d.push_back(3.0 * p.phi0.back() - 1.5 * p.phi1.back() + 0.01 * (u(rng) - 0.5));
  }
  double g[4] = {0, 0, 0, 0}, h[2] = {0, 0};
  for (int i = 0; i < n; ++i) {
    g[0] += p.w[i] * p.phi0[i] * p.phi0[i];
    g[1] += p.w[i] * p.phi0[i] * p.phi1[i];
    g[3] += p.w[i] * p.phi1[i] * p.phi1[i];
    h[0] += p.w[i] * p.phi0[i] * p.d[i];
    h[1] += p.w[i] * p.phi1[i] * p.d[i];
  }
  g[2] = g[1];
  p.ok = solve_linear_amplitudes(g, h, &p.la);
  return p;
}

// sum w r phi_k over the pixels, relative to sum w |r phi_k|.
double relative_dot(const Pair& p, const std::vector<double>& r, const std::vector<double>& phi) {
  double dot = 0, scale = 0;
  for (std::size_t i = 0; i < r.size(); ++i) {
    dot += p.w[i] * r[i] * phi[i];
    scale += std::abs(p.w[i] * r[i] * phi[i]);
  }
  return std::abs(dot) / scale;
}

TEST(VariableProjection, AmplitudesAreTheWeightedLeastSquaresSolution) {
  std::mt19937 rng(3);
  const Pair p = make_pair(400, 0.0, rng);
  ASSERT_TRUE(p.ok);
  // Direct: sqrt(W) Phi a = sqrt(W) d by QR.
  Eigen::MatrixXd a(400, 2);
  Eigen::VectorXd b(400);
  for (int i = 0; i < 400; ++i) {
    const double s = std::sqrt(p.w[i]);
    a(i, 0) = s * p.phi0[i];
    a(i, 1) = s * p.phi1[i];
    b(i) = s * p.d[i];
  }
  const Eigen::Vector2d x = a.colPivHouseholderQr().solve(b);
  EXPECT_NEAR(p.la.a[0], x(0), 1e-10 * std::abs(x(0)));
  EXPECT_NEAR(p.la.a[1], x(1), 1e-10 * std::abs(x(1)));
  // The residual is W-orthogonal to both images (what makes J^T W r exact after projection).
  std::vector<double> r(400);
  for (int i = 0; i < 400; ++i) r[i] = p.d[i] - p.la.a[0] * p.phi0[i] - p.la.a[1] * p.phi1[i];
  EXPECT_LT(relative_dot(p, r, p.phi0), 1e-12);
  EXPECT_LT(relative_dot(p, r, p.phi1), 1e-12);
}

TEST(VariableProjection, ProjectedColumnIsWOrthogonalToBothImages) {
  std::mt19937 rng(5);
  const Pair p = make_pair(300, 0.0, rng);
  ASSERT_TRUE(p.ok);
  std::vector<double> column(300), out(300);
  for (int i = 0; i < 300; ++i) column[i] = std::sin(0.05 * i) + 2.0 * p.phi0[i];
  project_out(p.la, p.w.data(), p.phi0.data(), p.phi1.data(), column.data(), out.data(), 300);
  EXPECT_LT(relative_dot(p, out, p.phi0), 1e-12);
  EXPECT_LT(relative_dot(p, out, p.phi1), 1e-12);
  // In place gives the same.
  project_out(p.la, p.w.data(), p.phi0.data(), p.phi1.data(), column.data(), column.data(), 300);
  EXPECT_EQ(column, out);
}

TEST(VariableProjection, IndistinguishableImagesGetFiniteAmplitudesAlongTheirCommonDirection) {
  std::mt19937 rng(11);
  const Pair p = make_pair(200, 3.0, rng);  // phi1 = 3 phi0: G has rank one
  ASSERT_TRUE(p.ok);
  ASSERT_TRUE(std::isfinite(p.la.a[0]) && std::isfinite(p.la.a[1]));
  // The minimum-norm solution: a along (1, 3), and the model the best fit along phi0.
  EXPECT_NEAR(p.la.a[1], 3.0 * p.la.a[0], 1e-9 * std::abs(p.la.a[1]));
  std::vector<double> r(200);
  for (int i = 0; i < 200; ++i) r[i] = p.d[i] - p.la.a[0] * p.phi0[i] - p.la.a[1] * p.phi1[i];
  EXPECT_LT(relative_dot(p, r, p.phi0), 1e-10);
  std::vector<double> out(200);
  project_out(p.la, p.w.data(), p.phi0.data(), p.phi1.data(), p.d.data(), out.data(), 200);
  EXPECT_LT(relative_dot(p, out, p.phi0), 1e-10);
}

TEST(VariableProjection, NoWeightedPixelIsRefused) {
  const double g[4] = {0, 0, 0, 0}, h[2] = {0, 0};
  LinearAmplitudes la;
  EXPECT_FALSE(solve_linear_amplitudes(g, h, &la));
  const double g_nan[4] = {1, NAN, NAN, 1};
  EXPECT_FALSE(solve_linear_amplitudes(g_nan, h, &la));
}

}  // namespace
}  // namespace stampede
