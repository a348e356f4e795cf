// Tests of the periodic copies' light (kernels/wrapped_wings): the second-order blur against a
// direct convolution, its derivatives against central differences, the copy bound, and the
// Chebyshev interpolation of the stamp.
#include "kernels/wrapped_wings.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "kernels/sersic.hpp"

namespace stampede::kernels {
namespace {

WingComponent component(double n, double e1, double e2, double r, double x0, double y0) {
  WingComponent c;
  c.x0 = x0;
  c.y0 = y0;
  c.q = ellipse_quadratic(e1, e2, r);
  c.b = sersic_b(n);
  c.s = 0.5 / n;
  c.root = n == 1 ? SersicRoot::kSquareRoot : n == 4 ? SersicRoot::kEighthRoot : SersicRoot::kGeneralPow;
  ellipse_quadratic_derivatives(e1, e2, r, &c.dq_de1, &c.dq_de2);
  c.du_dr_over_u = -2.0 / r;  // q scales as 1 / r^2
  return c;
}

double unblurred(const WingComponent& c, double x, double y) {
  return std::exp(-c.b * std::pow(c.q(x - c.x0, y - c.y0), c.s));
}

// Far from the centre the profile convolved with a Gaussian of covariance M is the profile plus
// exp(1/2 M : grad grad I / I), to (sigma / scale)^4: against a direct convolution (a fine midpoint
// rule over +-7 sigma), that form leaves < 3 % of the blur's effect at 30-60 px
// for both indices.
TEST(WrappedWings, SecondOrderBlurMatchesConvolutionFarOut) {
  const BlurMoments m{2.0, 0.3, 1.6};
  const double det = m.xx * m.yy - m.xy * m.xy, ixx = m.yy / det, ixy = -m.xy / det, iyy = m.xx / det;
  const double h = 0.02, reach = 7 * std::sqrt(std::max(m.xx, m.yy));
  for (double n : {1.0, 4.0})
    for (double d : {30.0, 45.0, 60.0}) {
      const WingComponent c = component(n, 0.2, -0.1, n == 1 ? 4.0 : 2.5, 0.3, -0.2);
      const double x = d * 0.8, y = d * 0.6;
      double conv = 0, norm = 0;
      for (double zy = -reach + h / 2; zy < reach; zy += h)
        for (double zx = -reach + h / 2; zx < reach; zx += h) {
          const double g = std::exp(-0.5 * (ixx * zx * zx + 2 * ixy * zx * zy + iyy * zy * zy));
          conv += g * unblurred(c, x - zx, y - zy);
          norm += g;
        }
      conv /= norm;
      const double plain = unblurred(c, x, y), blurred = blurred_wing(c, m, x, y, nullptr);
      const double left = std::abs(blurred - conv) / std::abs(conv - plain);
      std::printf("n %.0f d %.0f: blur changes the wing by %.2e, second order leaves %.2e of that\n", n, d,
                  conv / plain - 1, left);
      EXPECT_LT(left, 0.03) << "n " << n << " d " << d;
    }
}

TEST(WrappedWings, DerivativesMatchCentralDifferences) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  const BlurMoments m{3.9, 0.1, 4.1};
  for (int set = 0; set < 20; ++set) {
    const double n = set % 2 ? 4.0 : 1.0;
    const double e1 = 0.6 * u(rng), e2 = 0.3 * u(rng), r = 2.0 + 1.5 * u(rng), x0 = 19 + 3 * u(rng), y0 = 19 + 3 * u(rng);
    const double x = 19 + 70 * u(rng), y = 19 + (set % 3 ? 70.0 : -70.0);
    std::array<double, kWingDerivatives> d{};
    const double v = blurred_wing(component(n, e1, e2, r, x0, y0), m, x, y, &d);
    ASSERT_GT(v, 0);
    const double h[kWingDerivatives] = {1e-5, 1e-5, 1e-6, 1e-6, 1e-6};
    for (int k = 0; k < kWingDerivatives; ++k) {
      double p[5] = {x0, y0, e1, e2, r}, q[5] = {x0, y0, e1, e2, r};
      p[k] += h[k];
      q[k] -= h[k];
      const double plus = blurred_wing(component(n, p[2], p[3], p[4], p[0], p[1]), m, x, y, nullptr);
      const double minus = blurred_wing(component(n, q[2], q[3], q[4], q[0], q[1]), m, x, y, nullptr);
      const double fd = (plus - minus) / (2 * h[k]);
      EXPECT_NEAR(d[k], fd, 1e-6 * std::abs(fd) + 1e-9 * v / h[k]) << "set " << set << " derivative " << k;
    }
  }
}

// The copies left out are below the floor at every stamp pixel, blurred.
TEST(WrappedWings, SignificantCopiesBoundTheOmittedLight) {
  const int n = 96, size = 39, rings = 6;
  for (double e1 : {0.0, 0.7})
    for (double r : {1.0, 3.0, 8.0}) {
      const WingComponent c = component(4.0, e1, 0.0, r, 21.0, 17.0);
      const BlurMoments m{3.9, 0.0, 3.9};
      const double floor = 1e-8;
      std::vector<CopyOffset> kept;
      kept.reserve((2 * rings + 1) * (2 * rings + 1));
      significant_copies(c, n, size, rings, floor, &kept);
      int omitted_above = 0;
      for (int j = -rings; j <= rings; ++j)
        for (int i = -rings; i <= rings; ++i) {
          if (i == 0 && j == 0) continue;
          bool is_kept = false;
          for (const CopyOffset& o : kept) is_kept |= o.dx == i * n && o.dy == j * n;
          if (is_kept) continue;
          double largest = 0;
          for (int y = 0; y < size; ++y)
            for (int x = 0; x < size; ++x) largest = std::max(largest, blurred_wing(c, m, x - i * n, y - j * n, nullptr));
          omitted_above += largest > floor;
        }
      std::printf("e1 %.1f r_e %.0f: %zu copies kept\n", e1, r, kept.size());
      EXPECT_EQ(omitted_above, 0) << "e1 " << e1 << " r " << r;
    }
}

// Tensor-product interpolation at Chebyshev nodes reproduces polynomials below the node count
// exactly, and converges geometrically for a function analytic near the stamp.
TEST(WrappedWings, ChebyshevStampInterpolates) {
  const int size = 39;
  for (int nodes : {4, 8, 12}) {
    const ChebyshevStamp cs(size, nodes);
    std::vector<double> v(static_cast<std::size_t>(nodes) * nodes), out(size * size, 0.0), scratch(nodes * size);
    auto poly = [&](double x, double y) { return std::pow(0.1 * x - 1, nodes - 1) * (1 + 0.05 * y) + 0.01 * x * y; };
    for (int j = 0; j < nodes; ++j)
      for (int i = 0; i < nodes; ++i) v[j * nodes + i] = poly(cs.node(i), cs.node(j));
    cs.add_interpolated(v.data(), out.data(), scratch.data());
    double worst = 0;
    for (int y = 0; y < size; ++y)
      for (int x = 0; x < size; ++x) worst = std::max(worst, std::abs(out[y * size + x] - poly(x, y)));
    EXPECT_LT(worst, 1e-9) << nodes << " nodes";
  }
  double previous = INFINITY;
  for (int nodes : {4, 8, 12, 16}) {
    const ChebyshevStamp cs(size, nodes);
    std::vector<double> v(static_cast<std::size_t>(nodes) * nodes), out(size * size, 0.0), scratch(nodes * size);
    auto f = [](double x, double y) { return std::exp(-std::sqrt((x - 110) * (x - 110) + (y + 40) * (y + 40)) / 9); };
    for (int j = 0; j < nodes; ++j)
      for (int i = 0; i < nodes; ++i) v[j * nodes + i] = f(cs.node(i), cs.node(j));
    cs.add_interpolated(v.data(), out.data(), scratch.data());
    double worst = 0;
    for (int y = 0; y < size; ++y)
      for (int x = 0; x < size; ++x) worst = std::max(worst, std::abs(out[y * size + x] - f(x, y)) / f(x, y));
    std::printf("%2d nodes: worst relative error %.2e\n", nodes, worst);
    EXPECT_LT(worst, previous / 10) << nodes << " nodes";
    previous = worst;
  }
}

}  // namespace
}  // namespace stampede::kernels
