// Sérsic sub-pixel rendering; see profile_render.hpp. The root is a template parameter so the
// pixel loops carry no branch on the Sérsic index.
#include "kernels/profile_render.hpp"

#include <algorithm>
#include <cmath>

namespace stampede::kernels {
namespace {

template <SersicRoot R>
inline double root_of(double u, double inv_2n) {
  if constexpr (R == SersicRoot::kSquareRoot) {
    return std::sqrt(u);
  } else if constexpr (R == SersicRoot::kEighthRoot) {
    return std::sqrt(std::sqrt(std::sqrt(u)));
  } else {
    return std::pow(u, inv_2n);
  }
}

// Offsets of the supersampling points from a sub-pixel centre, in data pixels.
struct SuperOffsets {
  std::array<double, 64> d{};
  int n = 1;
  SuperOffsets(int supersample, double step) : n(supersample) {
    for (int a = 0; a < n; ++a) d[a] = step * ((a + 0.5) / n - 0.5);
  }
};

template <SersicRoot R>
void accumulate_value_impl(const SubpixelGrid& grid, const GridRegion& region, int supersample,
                           const SersicBlock& block, double amplitude, double* out) {
  const SuperOffsets off(supersample, grid.step);
  const double scale = amplitude / (off.n * off.n);
  const EllipseQuadratic q = block.q;
  for (int j = region.y_begin; j < region.y_end; ++j) {
    const double yc = grid.origin + grid.step * j - block.y0;
    double* row = out + static_cast<std::ptrdiff_t>(j) * grid.size;
    for (int i = region.x_begin; i < region.x_end; ++i) {
      const double xc = grid.origin + grid.step * i - block.x0;
      double sum = 0.0;
      for (int b = 0; b < off.n; ++b) {
        const double dy = yc + off.d[b];
        for (int a = 0; a < off.n; ++a) {
          const double dx = xc + off.d[a];
          sum += std::exp(-block.b * root_of<R>(std::max(q(dx, dy), block.u_floor), block.inv_2n));
        }
      }
      row[i] += scale * sum;
    }
  }
}

template <SersicRoot R>
void accumulate_derivatives_impl(const SubpixelGrid& grid, const GridRegion& region, int supersample,
                                 const SersicDerivativeBlock& block, double* value,
                                 const std::array<double*, kNumShapeDerivatives>& derivative) {
  const SuperOffsets off(supersample, grid.step);
  const double mean = 1.0 / (off.n * off.n);
  const EllipseQuadratic q = block.shape.q;
  const EllipseQuadratic q1 = block.dq_de1;
  const EllipseQuadratic q2 = block.dq_de2;
  const double b = block.shape.b;
  const double inv_2n = block.shape.inv_2n;
  const double u_floor = block.shape.u_floor;
  // d value / du = -b value (du^(1/2n)/du) = -b value t inv_2n / u; the amplitude folds in here.
  const double g_scale = -block.amplitude * b * inv_2n;
  for (int j = region.y_begin; j < region.y_end; ++j) {
    const double yc = grid.origin + grid.step * j - block.shape.y0;
    const std::ptrdiff_t row = static_cast<std::ptrdiff_t>(j) * grid.size;
    for (int i = region.x_begin; i < region.x_end; ++i) {
      const double xc = grid.origin + grid.step * i - block.shape.x0;
      double v_sum = 0, sx = 0, sy = 0, s1 = 0, s2 = 0, sr = 0;
      for (int bb = 0; bb < off.n; ++bb) {
        const double dy = yc + off.d[bb];
        for (int a = 0; a < off.n; ++a) {
          const double dx = xc + off.d[a];
          const double u_raw = q(dx, dy);
          const double u = std::max(u_raw, u_floor);
          const double t = root_of<R>(u, inv_2n);
          const double v = std::exp(-b * t);
          // The profile's gradient is singular at u = 0 (a set of measure zero); take it as 0 there.
          const double g = u > 0.0 ? g_scale * v * t / u : 0.0;
          // Under the floor the value depends only on r (through u_floor), not on position or shape.
          const double gs = u_raw >= u_floor ? g : 0.0;
          v_sum += v;
          sx += gs * (q.xx * dx + q.xy * dy);
          sy += gs * (q.xy * dx + q.yy * dy);
          s1 += gs * q1(dx, dy);
          s2 += gs * q2(dx, dy);
          sr += g * u;
        }
      }
      if (value) value[row + i] = v_sum * mean;
      // du/dx0 = -2 (xx dx + xy dy), du/dy0 = -2 (xy dx + yy dy).
      derivative[kDx0][row + i] += -2.0 * sx * mean;
      derivative[kDy0][row + i] += -2.0 * sy * mean;
      derivative[kDe1][row + i] += s1 * mean;
      derivative[kDe2][row + i] += s2 * mean;
      derivative[kDr][row + i] += block.du_dr_over_u * sr * mean;
    }
  }
}

}  // namespace

SersicRoot sersic_root_for(double n) {
  if (n == 1.0) return SersicRoot::kSquareRoot;
  if (n == 4.0) return SersicRoot::kEighthRoot;
  return SersicRoot::kGeneralPow;
}

double sersic_value(const SersicBlock& block, double x, double y) {
  const double u = std::max(block.q(x - block.x0, y - block.y0), block.u_floor);
  return std::exp(-block.b * std::pow(u, block.inv_2n));
}

void accumulate_sersic(const SubpixelGrid& grid, const GridRegion& region, int supersample,
                       const SersicBlock& block, double amplitude, double* out) {
  if (region.empty()) return;
  switch (block.root) {
    case SersicRoot::kSquareRoot:
      return accumulate_value_impl<SersicRoot::kSquareRoot>(grid, region, supersample, block, amplitude, out);
    case SersicRoot::kEighthRoot:
      return accumulate_value_impl<SersicRoot::kEighthRoot>(grid, region, supersample, block, amplitude, out);
    case SersicRoot::kGeneralPow:
      return accumulate_value_impl<SersicRoot::kGeneralPow>(grid, region, supersample, block, amplitude, out);
  }
}

void accumulate_sersic_derivatives(const SubpixelGrid& grid, const GridRegion& region, int supersample,
                                   const SersicDerivativeBlock& block, double* value,
                                   const std::array<double*, kNumShapeDerivatives>& derivative) {
  if (region.empty()) return;
  switch (block.shape.root) {
    case SersicRoot::kSquareRoot:
      return accumulate_derivatives_impl<SersicRoot::kSquareRoot>(grid, region, supersample, block, value,
                                                                  derivative);
    case SersicRoot::kEighthRoot:
      return accumulate_derivatives_impl<SersicRoot::kEighthRoot>(grid, region, supersample, block, value,
                                                                  derivative);
    case SersicRoot::kGeneralPow:
      return accumulate_derivatives_impl<SersicRoot::kGeneralPow>(grid, region, supersample, block, value,
                                                                  derivative);
  }
}

}  // namespace stampede::kernels
