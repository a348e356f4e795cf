// Tests kernels/profile_render: sub-pixel accumulation against the single-point reference, the
// supersampling rule, region handling, the root special cases, and every analytic derivative image
// against central finite differences of the rendered value.
#include "kernels/profile_render.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <vector>

#include "kernels/ellipse.hpp"
#include "kernels/sersic.hpp"

namespace stampede::kernels {
namespace {

// The shape parameters the derivative kernel differentiates with respect to.
struct Shape {
  double x0, y0, e1, e2, r, n;
};

SersicBlock make_block(const Shape& s) {
  SersicBlock block;
  block.x0 = s.x0;
  block.y0 = s.y0;
  block.q = ellipse_quadratic(s.e1, s.e2, s.r);
  block.b = sersic_b(s.n);
  block.inv_2n = 0.5 / s.n;
  block.root = sersic_root_for(s.n);
  return block;
}

SersicDerivativeBlock make_derivative_block(const Shape& s, double amplitude) {
  SersicDerivativeBlock d;
  d.shape = make_block(s);
  d.amplitude = amplitude;
  ellipse_quadratic_derivatives(s.e1, s.e2, s.r, &d.dq_de1, &d.dq_de2);
  d.du_dr_over_u = -2.0 / s.r;  // u is proportional to 1 / r^2
  return d;
}

// A 24 x 24 grid of 0.25-pixel sub-pixels covering data pixels [-0.6, 5.4).
constexpr SubpixelGrid kGrid{24, -0.6, 0.25};
constexpr GridRegion kFull{0, 24, 0, 24};

double centre(const SubpixelGrid& g, int i) { return g.origin + g.step * i; }

// The s x s cell centres of sub-pixel i along one axis, computed from the cell edges (independent of
// the kernel's offset table).
std::vector<double> cell_centres(const SubpixelGrid& g, int i, int s) {
  std::vector<double> c(s);
  const double left = centre(g, i) - 0.5 * g.step;
  for (int a = 0; a < s; ++a) c[a] = left + g.step * (a + 0.5) / s;
  return c;
}

// Reference: the mean of sersic_value over the cell centres (explicit loop).
double reference_mean(const SubpixelGrid& g, const SersicBlock& block, int i, int j, int s) {
  const std::vector<double> xs = cell_centres(g, i, s), ys = cell_centres(g, j, s);
  double sum = 0.0;
  for (double y : ys)
    for (double x : xs) sum += sersic_value(block, x, y);
  return sum / (s * s);
}

const Shape kShapes[] = {
    {2.13, 1.77, 0.3, -0.2, 1.1, 1.0},   // exponential: kSquareRoot
    {2.41, 2.05, -0.15, 0.35, 0.9, 4.0},  // de Vaucouleurs: kEighthRoot
    {1.92, 2.30, 0.5, 0.1, 1.4, 2.5},    // general n: kGeneralPow
};

TEST(SersicRootFor, ChoosesSpecialCasesOnlyForExactIndices) {
  EXPECT_EQ(sersic_root_for(1.0), SersicRoot::kSquareRoot);
  EXPECT_EQ(sersic_root_for(4.0), SersicRoot::kEighthRoot);
  for (double n : {0.5, 0.999999, 1.000001, 2.0, 2.5, 3.999999, 4.000001, 8.0})
    EXPECT_EQ(sersic_root_for(n), SersicRoot::kGeneralPow) << "n = " << n;
}

TEST(AccumulateSersic, RootPathsMatchPow) {
  // The same block rendered with the special root and with the general pow path. The roots differ by
  // at most ~2 ulp and exp(-b t) turns that into a relative error ~ b t eps (<= 30 eps on this grid).
  for (double n : {1.0, 4.0}) {
    Shape s{2.0, 2.2, 0.2, 0.25, 1.2, n};
    SersicBlock special = make_block(s);
    ASSERT_NE(special.root, SersicRoot::kGeneralPow);
    SersicBlock general = special;
    general.root = SersicRoot::kGeneralPow;
    std::vector<double> a(kGrid.size * kGrid.size, 0.0), b(a.size(), 0.0);
    accumulate_sersic(kGrid, kFull, 2, special, 1.0, a.data());
    accumulate_sersic(kGrid, kFull, 2, general, 1.0, b.data());
    for (std::size_t k = 0; k < a.size(); ++k) EXPECT_NEAR(a[k], b[k], 1e-13 * b[k]) << "n = " << n << " k = " << k;
  }
}

TEST(AccumulateSersic, SupersampleOneIsValueAtSubpixelCentre) {
  // Same arithmetic as sersic_value except the root (sqrt vs pow): see RootPathsMatchPow for 1e-13.
  for (const Shape& s : kShapes) {
    const SersicBlock block = make_block(s);
    const double amplitude = 3.7;
    std::vector<double> out(kGrid.size * kGrid.size, 0.0);
    accumulate_sersic(kGrid, kFull, 1, block, amplitude, out.data());
    for (int j = 0; j < kGrid.size; ++j)
      for (int i = 0; i < kGrid.size; ++i) {
        const double expected = amplitude * sersic_value(block, centre(kGrid, i), centre(kGrid, j));
        EXPECT_NEAR(out[j * kGrid.size + i], expected, 1e-13 * expected) << "n = " << s.n << " (" << i << ", " << j << ")";
      }
  }
}

TEST(AccumulateSersic, SupersampleIsMeanOverCellCentres) {
  for (const Shape& s : kShapes) {
    const SersicBlock block = make_block(s);
    for (int ss : {2, 3, 5, 8}) {
      const double amplitude = 0.6;
      std::vector<double> out(kGrid.size * kGrid.size, 0.0);
      accumulate_sersic(kGrid, kFull, ss, block, amplitude, out.data());
      for (int j = 0; j < kGrid.size; ++j)
        for (int i = 0; i < kGrid.size; ++i) {
          const double expected = amplitude * reference_mean(kGrid, block, i, j, ss);
          // Cell centres computed two ways differ by ~1 ulp of the coordinate; the profile's
          // log-derivative is at most ~b (1/2n) u^(1/2n - 1/2) / r ~ 10 / pixel at these distances,
          // so 1e-12 relative bounds the effect with ample margin.
          EXPECT_NEAR(out[j * kGrid.size + i], expected, 1e-12 * expected)
              << "n = " << s.n << " s = " << ss << " (" << i << ", " << j << ")";
        }
    }
  }
}

TEST(AccumulateSersic, AddsIntoOutputAndLeavesOutsideRegionUntouched) {
  const SersicBlock block = make_block(kShapes[1]);
  const GridRegion region{3, 17, 5, 12};
  const double sentinel = 12345.0;
  std::vector<double> once(kGrid.size * kGrid.size, 0.0);
  accumulate_sersic(kGrid, region, 3, block, 2.0, once.data());
  std::vector<double> twice(kGrid.size * kGrid.size, sentinel);
  accumulate_sersic(kGrid, region, 3, block, 2.0, twice.data());
  accumulate_sersic(kGrid, region, 3, block, 2.0, twice.data());
  for (int j = 0; j < kGrid.size; ++j)
    for (int i = 0; i < kGrid.size; ++i) {
      const int k = j * kGrid.size + i;
      const bool inside = i >= region.x_begin && i < region.x_end && j >= region.y_begin && j < region.y_end;
      if (inside) {
        ASSERT_GT(once[k], 0.0);
        // sentinel + 2 v: rounding of the sum is ~eps * sentinel.
        EXPECT_NEAR(twice[k], sentinel + 2.0 * once[k], 1e-11) << "(" << i << ", " << j << ")";
      } else {
        EXPECT_EQ(once[k], 0.0) << "(" << i << ", " << j << ")";
        EXPECT_EQ(twice[k], sentinel) << "(" << i << ", " << j << ")";
      }
    }
}

TEST(AccumulateSersic, EmptyRegionWritesNothing) {
  const SersicBlock block = make_block(kShapes[0]);
  std::vector<double> out(kGrid.size * kGrid.size, -1.0);
  accumulate_sersic(kGrid, GridRegion{5, 5, 0, 24}, 1, block, 1.0, out.data());
  accumulate_sersic(kGrid, GridRegion{0, 24, 9, 3}, 1, block, 1.0, out.data());
  for (double v : out) EXPECT_EQ(v, -1.0);
}

TEST(AccumulateSersic, FineGridSumIsAnalyticFlux) {
  // Exponential disc (smooth away from a kink at the centre), sheared: the midpoint-rule sum over a
  // grid reaching 30 scale lengths along the major axis must give the analytic, shear-invariant flux.
  // Error sources: the centre kink, O(h^3) ~ 1e-6 of the flux at h = 0.05, and a truncated tail
  // < e^-25; 2e-5 relative is the stated bound.
  const Shape s{0.0, 0.0, 0.3, 0.2, 1.5, 1.0};
  const SersicBlock block = make_block(s);
  const int size = 1600;
  const SubpixelGrid grid{size, -0.05 * (size - 1) / 2.0, 0.05};
  std::vector<double> out(static_cast<std::size_t>(size) * size, 0.0);
  const double amplitude = 4.0;
  accumulate_sersic(grid, GridRegion{0, size, 0, size}, 1, block, amplitude, out.data());
  double sum = 0.0;
  for (double v : out) sum += v;
  sum *= grid.step * grid.step;
  EXPECT_NEAR(sum / sersic_flux(amplitude, s.r, s.n), 1.0, 2e-5);
}

// Central finite differences of amplitude * (supersampled) value with respect to one parameter.
// p: 0 x0, 1 y0, 2 e1, 3 e2, 4 r.
// floor_c > 0 sets u_floor = floor_c / r^2, which follows r as the renderer's h^2 / (pi r_e^2) does.
std::vector<double> finite_difference(const Shape& s, int p, double amplitude, int ss, double h, double floor_c = 0.0) {
  Shape plus = s, minus = s;
  double* fields_plus[] = {&plus.x0, &plus.y0, &plus.e1, &plus.e2, &plus.r};
  double* fields_minus[] = {&minus.x0, &minus.y0, &minus.e1, &minus.e2, &minus.r};
  *fields_plus[p] += h;
  *fields_minus[p] -= h;
  SersicBlock bp = make_block(plus), bm = make_block(minus);
  bp.u_floor = floor_c / (plus.r * plus.r);
  bm.u_floor = floor_c / (minus.r * minus.r);
  std::vector<double> vp(kGrid.size * kGrid.size, 0.0), vm(vp.size(), 0.0);
  accumulate_sersic(kGrid, kFull, ss, bp, amplitude, vp.data());
  accumulate_sersic(kGrid, kFull, ss, bm, amplitude, vm.data());
  for (std::size_t k = 0; k < vp.size(); ++k) vp[k] = (vp[k] - vm[k]) / (2 * h);
  return vp;
}

TEST(AccumulateSersicDerivatives, ValueIsUnitAmplitudeRender) {
  for (const Shape& s : kShapes) {
    for (int ss : {1, 3}) {
      const SersicDerivativeBlock d = make_derivative_block(s, 7.5);
      std::vector<double> value(kGrid.size * kGrid.size, -99.0);  // overwritten, not accumulated
      std::vector<std::vector<double>> deriv(kNumShapeDerivatives, std::vector<double>(value.size(), 0.0));
      std::array<double*, kNumShapeDerivatives> ptr;
      for (int p = 0; p < kNumShapeDerivatives; ++p) ptr[p] = deriv[p].data();
      accumulate_sersic_derivatives(kGrid, kFull, ss, d, value.data(), ptr);
      std::vector<double> ref(value.size(), 0.0);
      accumulate_sersic(kGrid, kFull, ss, d.shape, 1.0, ref.data());
      // Same sums in the same order; only the final scaling is written differently: a few ulp.
      for (std::size_t k = 0; k < ref.size(); ++k)
        EXPECT_NEAR(value[k], ref[k], 1e-14 * ref[k]) << "n = " << s.n << " s = " << ss << " k = " << k;
    }
  }
}

TEST(AccumulateSersicDerivatives, MatchFiniteDifferences) {
  const double amplitude = 50.0;
  // Step 1e-5 in pixels / ellipticity units. Truncation error h^2 f''' / 6 is ~(h / d)^2 of the
  // derivative at distance d >= 0.3 r_e from the centre (~1e-9); rounding is eps A / h ~ 5e-10.
  // So 1e-6 relative, with an absolute floor of 1e-7 A (for pixels where a derivative crosses zero,
  // e.g. d/dx0 on the line through the centre), is a bound with two orders of margin.
  const double h = 1e-5;
  const char* names[] = {"x0", "y0", "e1", "e2", "r"};
  for (const Shape& s : kShapes) {
    for (int ss : {1, 3}) {
      const SersicDerivativeBlock d = make_derivative_block(s, amplitude);
      std::vector<std::vector<double>> deriv(kNumShapeDerivatives,
                                             std::vector<double>(kGrid.size * kGrid.size, 0.0));
      std::array<double*, kNumShapeDerivatives> ptr;
      for (int p = 0; p < kNumShapeDerivatives; ++p) ptr[p] = deriv[p].data();
      accumulate_sersic_derivatives(kGrid, kFull, ss, d, nullptr, ptr);
      int checked = 0;
      for (int p = 0; p < kNumShapeDerivatives; ++p) {
        const std::vector<double> fd = finite_difference(s, p, amplitude, ss, h);
        for (int j = 0; j < kGrid.size; ++j)
          for (int i = 0; i < kGrid.size; ++i) {
            // Away from the cusp: every supersampling point has u >= 0.1.
            const double half = 0.5 * kGrid.step;
            double u_min = INFINITY;
            for (double dy : {-half, 0.0, half})
              for (double dx : {-half, 0.0, half})
                u_min = std::min(u_min, d.shape.q(centre(kGrid, i) + dx - s.x0, centre(kGrid, j) + dy - s.y0));
            if (u_min < 0.1) continue;
            const int k = j * kGrid.size + i;
            EXPECT_NEAR(deriv[p][k], fd[k], 1e-6 * std::abs(fd[k]) + 1e-7 * amplitude)
                << "d/d" << names[p] << " n = " << s.n << " s = " << ss << " (" << i << ", " << j << ")";
            ++checked;
          }
      }
      EXPECT_GT(checked, 5 * 400) << "too few pixels away from the centre were checked";
    }
  }
}

TEST(AccumulateSersicDerivatives, DerivativesAccumulateAndRespectRegion) {
  const SersicDerivativeBlock d = make_derivative_block(kShapes[2], 3.0);
  const GridRegion region{2, 20, 6, 15};
  const double sentinel = -7.0;
  std::vector<std::vector<double>> once(kNumShapeDerivatives, std::vector<double>(kGrid.size * kGrid.size, 0.0));
  std::vector<std::vector<double>> twice(kNumShapeDerivatives,
                                         std::vector<double>(kGrid.size * kGrid.size, sentinel));
  std::vector<double> value(kGrid.size * kGrid.size, sentinel);
  std::array<double*, kNumShapeDerivatives> p_once, p_twice;
  for (int p = 0; p < kNumShapeDerivatives; ++p) {
    p_once[p] = once[p].data();
    p_twice[p] = twice[p].data();
  }
  accumulate_sersic_derivatives(kGrid, region, 2, d, nullptr, p_once);
  accumulate_sersic_derivatives(kGrid, region, 2, d, value.data(), p_twice);
  accumulate_sersic_derivatives(kGrid, region, 2, d, value.data(), p_twice);
  for (int j = 0; j < kGrid.size; ++j)
    for (int i = 0; i < kGrid.size; ++i) {
      const int k = j * kGrid.size + i;
      const bool inside = i >= region.x_begin && i < region.x_end && j >= region.y_begin && j < region.y_end;
      if (inside) {
        EXPECT_GT(value[k], 0.0);
        for (int p = 0; p < kNumShapeDerivatives; ++p)
          EXPECT_NEAR(twice[p][k], sentinel + 2.0 * once[p][k], 1e-12 * (std::abs(sentinel) + std::abs(once[p][k])));
      } else {
        EXPECT_EQ(value[k], sentinel);
        for (int p = 0; p < kNumShapeDerivatives; ++p) {
          EXPECT_EQ(once[p][k], 0.0);
          EXPECT_EQ(twice[p][k], sentinel);
        }
      }
    }
}

// ---------------------------------------------------------------------------------------------
// The cusp floor: samples with u < u_floor take the value at u_floor.

TEST(AccumulateSersic, FloorClampsSamplesInsideIt) {
  for (const Shape& s : kShapes) {
    SersicBlock block = make_block(s);
    block.u_floor = 0.08;
    const double floored = std::exp(-block.b * std::pow(0.08, block.inv_2n));
    // sersic_value: constant inside the floor, unchanged outside it.
    EXPECT_NEAR(sersic_value(block, s.x0, s.y0), floored, 1e-15);
    EXPECT_NEAR(sersic_value(block, s.x0 + 0.01, s.y0 - 0.02), floored, 1e-15);
    const SersicBlock unfloored = make_block(s);
    EXPECT_EQ(sersic_value(block, s.x0 + 1.0, s.y0 + 0.5), sersic_value(unfloored, s.x0 + 1.0, s.y0 + 0.5));
    // The grid kernel applies the same rule at every sample (and agrees with sersic_value).
    std::vector<double> out(kGrid.size * kGrid.size, 0.0);
    accumulate_sersic(kGrid, kFull, 3, block, 2.0, out.data());
    int inside = 0;
    for (int j = 0; j < kGrid.size; ++j)
      for (int i = 0; i < kGrid.size; ++i) {
        const double expected = 2.0 * reference_mean(kGrid, block, i, j, 3);
        EXPECT_NEAR(out[j * kGrid.size + i], expected, 1e-12 * expected) << "n = " << s.n << " (" << i << ", " << j << ")";
        inside += block.q(centre(kGrid, i) - s.x0, centre(kGrid, j) - s.y0) < 0.08 ? 1 : 0;
      }
    EXPECT_GT(inside, 0) << "no sub-pixel centre fell inside the floor; the test tests nothing";
  }
}

TEST(AccumulateSersicDerivatives, FloorFreezesShapeDerivativesAndFollowsRadius) {
  // supersample 1, so each sub-pixel is one sample and can be classified against the floor. Inside
  // it the value depends on r only (u_floor = c / r^2), so d/dx0, d/dy0, d/de1, d/de2 are exactly 0
  // and d/dr matches finite differences of the floored render; outside it nothing changes. Samples
  // within 20% of the floor's edge are skipped (the kink spoils the central difference there).
  // Tolerances as in MatchFiniteDifferences.
  const double amplitude = 50.0, h = 1e-5, floor_c = 0.3;
  const char* names[] = {"x0", "y0", "e1", "e2", "r"};
  for (const Shape& s : kShapes) {
    SersicDerivativeBlock d = make_derivative_block(s, amplitude);
    d.shape.u_floor = floor_c / (s.r * s.r);
    std::vector<std::vector<double>> deriv(kNumShapeDerivatives, std::vector<double>(kGrid.size * kGrid.size, 0.0));
    std::array<double*, kNumShapeDerivatives> ptr;
    for (int p = 0; p < kNumShapeDerivatives; ++p) ptr[p] = deriv[p].data();
    std::vector<double> value(kGrid.size * kGrid.size, 0.0);
    accumulate_sersic_derivatives(kGrid, kFull, 1, d, value.data(), ptr);
    int inside = 0, outside = 0;
    for (int p = 0; p < kNumShapeDerivatives; ++p) {
      const std::vector<double> fd = finite_difference(s, p, amplitude, 1, h, floor_c);
      for (int j = 0; j < kGrid.size; ++j)
        for (int i = 0; i < kGrid.size; ++i) {
          const int k = j * kGrid.size + i;
          const double ratio = d.shape.q(centre(kGrid, i) - s.x0, centre(kGrid, j) - s.y0) / d.shape.u_floor;
          if (ratio > 0.8 && ratio < 1.2) continue;
          if (ratio < 1.0) {
            ++inside;
            if (p != kDr) {
              EXPECT_EQ(deriv[p][k], 0.0) << "d/d" << names[p] << " inside the floor, n = " << s.n;
              EXPECT_EQ(fd[k], 0.0) << "the floored render still moves with " << names[p];
            } else {
              EXPECT_GT(deriv[p][k], 0.0) << "a larger r lowers u_floor and raises the floored value";
            }
          } else {
            ++outside;
          }
          // Away from the cusp (u >= 0.1), or frozen inside the floor: a smooth function of each
          // parameter, so the central difference applies.
          if (ratio < 1.0 || ratio * d.shape.u_floor >= 0.1) {
            EXPECT_NEAR(deriv[p][k], fd[k], 1e-6 * std::abs(fd[k]) + 1e-7 * amplitude)
                << "d/d" << names[p] << " n = " << s.n << " (" << i << ", " << j << ") u/u_floor = " << ratio;
          }
        }
    }
    EXPECT_GT(inside, 0) << "n = " << s.n;
    EXPECT_GT(outside, 0) << "n = " << s.n;
    // The value image is the floored unit-amplitude render.
    std::vector<double> ref(value.size(), 0.0);
    accumulate_sersic(kGrid, kFull, 1, d.shape, 1.0, ref.data());
    for (std::size_t k = 0; k < ref.size(); ++k) EXPECT_NEAR(value[k], ref[k], 1e-14 * ref[k]);
  }
}

}  // namespace
}  // namespace stampede::kernels
