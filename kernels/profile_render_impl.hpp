// The Sérsic sub-pixel kernels written once over a lane type T: `double` (the scalar reference) or
// xsimd::batch<double, Arch>. Included only by the per-ISA translation units
// (profile_render_<isa>.cpp), each compiled with its instruction set's flags; never by headers.
// Everything here has internal linkage, so no inline function compiled for one ISA can be picked
// by the linker for another.
#pragma once

#include <algorithm>
#include <array>
#include <cmath>
#include <cstddef>
#include <type_traits>

#include "kernels/lanes.hpp"
#include "kernels/profile_render.hpp"

namespace stampede::kernels {
namespace {

// t = u^(1/2n) and t / u (the gradient's factor) for u > 0. The scalar reference and the AVX2 and
// SSE4.2 builds take square roots and divide; AVX-512 refines reciprocal-square-root estimates
// (u^-1/2, or u^-1/8 for n = 4), since its vector sqrt and div run no faster per element than
// scalar ones.
template <class T>
struct Root {
  T t, t_over_u;
};

template <class T, SersicRoot R>
inline Root<T> root_and_ratio(T u, double inv_2n) {
  using L = Lanes<T>;
  if constexpr (R == SersicRoot::kGeneralPow) {
    const T t = L::pow(u, inv_2n);
    return {t, t / u};
  } else if constexpr (!Lanes<T>::kEstimatedRsqrt) {
    const T t = R == SersicRoot::kSquareRoot ? L::sqrt(u) : L::sqrt(L::sqrt(L::sqrt(u)));  // no pow for n = 4
    return {t, t / u};
  } else if constexpr (R == SersicRoot::kSquareRoot) {
    const T a = L::rsqrt(u);  // u^-1/2
    return {u * a, a};
  } else {
    const T c = L::inverse_eighth_root(u);  // u^-1/8
    const T c2 = c * c, c7 = c2 * c2 * c2 * c;
    return {u * c7, c7};
  }
}

template <class T, SersicRoot R>
inline T root_of(T u, double inv_2n) {
  return root_and_ratio<T, R>(u, inv_2n).t;
}

struct SuperOffsets {
  std::array<double, 64> d{};
  int n = 1;
  SuperOffsets(int supersample, double step) : n(supersample) {
    for (int a = 0; a < n; ++a) d[a] = step * ((a + 0.5) / n - 0.5);
  }
};

// The floor applied to u: u_floor, and never 0, where the gradient's t / u is singular (a point
// exactly at the centre with no floor: u = 1e-300 gives the value 1 and gradient terms that vanish
// with dx, dy and u).
inline double positive_floor(const SersicBlock& block) { return std::max(block.u_floor, 1e-300); }

template <class T>
inline T quadratic_form(const EllipseQuadratic& q, T dx, T dy) {
  return (T(q.xx) * dx + T(2.0 * q.xy) * dy) * dx + T(q.yy) * dy * dy;
}

// The profile at offsets (dx, dy) from the centre (one per lane).
template <class T, SersicRoot R>
inline T value_at(T dx, T dy, const SersicBlock& block) {
  using L = Lanes<T>;
  const EllipseQuadratic q = block.q;
  const T u = quadratic_form(q, dx, dy);
  return L::exp(T(-block.b) * root_of<T, R>(L::max(u, T(positive_floor(block))), block.inv_2n));
}

// Sub-pixels [i, i + lanes) of row j: value sum over the supersampling points.
template <class T, SersicRoot R>
inline T value_sum(T xc, double yc, const SuperOffsets& off, const SersicBlock& block) {
  T sum(0.0);
  for (int bb = 0; bb < off.n; ++bb) {
    const T dy(yc + off.d[bb]);
    for (int a = 0; a < off.n; ++a) sum += value_at<T, R>(xc + T(off.d[a]), dy, block);
  }
  return sum;
}

template <class T>
struct DerivativeSums {  // no member initialisers: arrays of them are left for the kernel to zero
  T v, sx, sy, s1, s2, sr;
  static DerivativeSums zero() { return {T(0.0), T(0.0), T(0.0), T(0.0), T(0.0), T(0.0)}; }
};

// The derivative block with the per-sub-pixel mean and the constant factors of the gradient
// folded into its coefficients once per call, so each point's terms come out final.
struct DerivativeForms {
  SersicBlock shape;
  double g_scale;            // d value / du = g_scale value t / u (amplitude, -b, 1/2n and the mean)
  double x0_x, x0_y, y0_y;   // du/dx0 = x0_x dx + x0_y dy, du/dy0 = x0_y dx + y0_y dy
  EllipseQuadratic e1, e2;   // du/de1, du/de2 as quadratic forms
  double r;                  // du/dr / u
  double mean;               // 1 / points per sub-pixel
  DerivativeForms(const SersicDerivativeBlock& block, int supersample) : shape(block.shape) {
    mean = 1.0 / (supersample * supersample);
    g_scale = -block.amplitude * shape.b * shape.inv_2n * mean;
    const EllipseQuadratic& q = shape.q;
    x0_x = -2.0 * q.xx;
    x0_y = -2.0 * q.xy;
    y0_y = -2.0 * q.yy;
    e1 = block.dq_de1;
    e2 = block.dq_de2;
    r = block.du_dr_over_u;
  }
};

// Adds the value and the derivative terms at offsets (dx, dy) from the centre (one per lane).
template <class T, SersicRoot R>
inline void add_derivative_terms(T dx, T dy, const DerivativeForms& f, DerivativeSums<T>& s) {
  using L = Lanes<T>;
  const EllipseQuadratic q = f.shape.q, q1 = f.e1, q2 = f.e2;
  const T u_raw = quadratic_form(q, dx, dy);  // as value_at: the value image is the same to the bit
  const T xx = dx * dx, xy = dx * dy, yy = dy * dy;  // shared by the shape derivatives' forms
  const T u = L::max(u_raw, T(positive_floor(f.shape)));
  const Root<T> root = root_and_ratio<T, R>(u, f.shape.inv_2n);
  const T v = L::exp(T(-f.shape.b) * root.t);
  const T g = T(f.g_scale) * v * root.t_over_u;
  // Under the floor the value depends only on r (through u_floor), not on position or shape.
  const T gs = L::select(u_raw >= T(f.shape.u_floor), g, T(0.0));
  s.v += v;
  s.sx += gs * (T(f.x0_x) * dx + T(f.x0_y) * dy);
  s.sy += gs * (T(f.x0_y) * dx + T(f.y0_y) * dy);
  s.s1 += gs * (T(q1.xx) * xx + T(2.0 * q1.xy) * xy + T(q1.yy) * yy);
  s.s2 += gs * (T(q2.xx) * xx + T(2.0 * q2.xy) * xy + T(q2.yy) * yy);
  s.sr += g * (u * T(f.r));
}

template <class T, SersicRoot R>
inline DerivativeSums<T> derivative_sums(T xc, double yc, const SuperOffsets& off, const DerivativeForms& block) {
  DerivativeSums<T> s = DerivativeSums<T>::zero();
  for (int bb = 0; bb < off.n; ++bb) {
    const T dy(yc + off.d[bb]);
    for (int a = 0; a < off.n; ++a) add_derivative_terms<T, R>(xc + T(off.d[a]), dy, block, s);
  }
  return s;
}

// A supersampled block (the N_u x N_u central sub-pixels, U2^2 points each): lanes run over
// sub-pixels, W at a time, each lane summing its own sub-pixel's points in the scalar reference's
// order (even and odd points apart, then together), so no lane idles and no horizontal sum is
// needed. The sub-pixels left over (fewer than W)
// are vectorised over their points instead.
constexpr int kMaxBlockSubpixels = 256;
constexpr int kMaxBlockPoints = 1024;

struct SupersampledBlock {
  std::array<double, kMaxBlockSubpixels> cx, cy;  // sub-pixel centres relative to the profile centre
  std::array<double, kMaxBlockPoints> px, py;     // the points' offsets within a sub-pixel
  int subpixels = 0, points = 0;
  static bool fits(const GridRegion& region, int supersample) {
    return supersample > 1 && (region.x_end - region.x_begin) * (region.y_end - region.y_begin) <= kMaxBlockSubpixels &&
           supersample * supersample <= kMaxBlockPoints;
  }
  SupersampledBlock(const SubpixelGrid& grid, const GridRegion& region, const SuperOffsets& off, double x0, double y0) {
    for (int j = region.y_begin; j < region.y_end; ++j)
      for (int i = region.x_begin; i < region.x_end; ++i) {
        cx[static_cast<std::size_t>(subpixels)] = grid.origin + grid.step * i - x0;
        cy[static_cast<std::size_t>(subpixels++)] = grid.origin + grid.step * j - y0;
      }
    for (int bb = 0; bb < off.n; ++bb)
      for (int a = 0; a < off.n; ++a) {
        px[static_cast<std::size_t>(points)] = off.d[static_cast<std::size_t>(a)];
        py[static_cast<std::size_t>(points++)] = off.d[static_cast<std::size_t>(bb)];
      }
  }
};

template <class T, SersicRoot R>
void accumulate_value_block(const SubpixelGrid& grid, const GridRegion& region, const SuperOffsets& off,
                            const SersicBlock& block, double scale, double* out) {
  using L = Lanes<T>;
  constexpr int W = L::size;
  const SupersampledBlock sb(grid, region, off, block.x0, block.y0);
  std::array<double, kMaxBlockSubpixels> sums;
  int s = 0;
  for (; s + W <= sb.subpixels; s += W) {
    const T cx = L::load(&sb.cx[s]), cy = L::load(&sb.cy[s]);
    T acc(0.0), odd(0.0);  // even and odd points: two independent chains in flight
    int k = 0;
    for (; k + 2 <= sb.points; k += 2) {
      acc += value_at<T, R>(cx + T(sb.px[k]), cy + T(sb.py[k]), block);
      odd += value_at<T, R>(cx + T(sb.px[k + 1]), cy + T(sb.py[k + 1]), block);
    }
    if (k < sb.points) acc += value_at<T, R>(cx + T(sb.px[k]), cy + T(sb.py[k]), block);
    acc += odd;
    L::store(&sums[s], acc);
  }
  for (; s < sb.subpixels; ++s) {  // vectorised over points
    const T cx(sb.cx[s]), cy(sb.cy[s]);
    T acc(0.0);
    int k = 0;
    for (; k + W <= sb.points; k += W) acc += value_at<T, R>(cx + L::load(&sb.px[k]), cy + L::load(&sb.py[k]), block);
    double sum = L::sum(acc);
    for (; k < sb.points; ++k) sum += value_at<double, R>(sb.cx[s] + sb.px[k], sb.cy[s] + sb.py[k], block);
    sums[s] = sum;
  }
  s = 0;
  for (int j = region.y_begin; j < region.y_end; ++j) {
    double* row = out + static_cast<std::ptrdiff_t>(j) * grid.size;
    for (int i = region.x_begin; i < region.x_end; ++i) row[i] += scale * sums[s++];
  }
}

template <class T, SersicRoot R>
void accumulate_value_rows(const SubpixelGrid& grid, const GridRegion& region, int supersample,
                           const SersicBlock& block, double amplitude, double* out) {
  using L = Lanes<T>;
  constexpr int W = L::size;
  const SuperOffsets off(supersample, grid.step);
  const double scale = amplitude / (off.n * off.n);
  const T lane_x = L::iota() * T(grid.step);
  if (SupersampledBlock::fits(region, supersample)) {
    accumulate_value_block<T, R>(grid, region, off, block, scale, out);
    return;
  }
  for (int j = region.y_begin; j < region.y_end; ++j) {
    const double yc = grid.origin + grid.step * j - block.y0;
    double* row = out + static_cast<std::ptrdiff_t>(j) * grid.size;
    int i = region.x_begin;
    if (off.n == 1) {  // one sample per sub-pixel (all but the central block): two vectors at a time
      const T dy(yc);
      for (; i + 2 * W <= region.x_end; i += 2 * W) {
        // Each vector's offsets computed as in the one-vector loop: identical rounding whatever W.
        const T xc0 = T(grid.origin + grid.step * i - block.x0) + lane_x;
        const T xc1 = T(grid.origin + grid.step * (i + W) - block.x0) + lane_x;
        const T v0 = value_at<T, R>(xc0, dy, block), v1 = value_at<T, R>(xc1, dy, block);
        L::store(row + i, L::load(row + i) + T(scale) * v0);
        L::store(row + i + W, L::load(row + i + W) + T(scale) * v1);
      }
    }
    for (; i + W <= region.x_end; i += W) {
      const T xc = T(grid.origin + grid.step * i - block.x0) + lane_x;
      L::store(row + i, L::load(row + i) + T(scale) * value_sum<T, R>(xc, yc, off, block));
    }
    for (; i < region.x_end; ++i) {  // the row's tail, one lane at a time
      const double xc = grid.origin + grid.step * i - block.x0;
      row[i] += scale * value_sum<double, R>(xc, yc, off, block);
    }
  }
}

template <class T, SersicRoot R>
void accumulate_derivative_rows(const SubpixelGrid& grid, const GridRegion& region, int supersample,
                                const SersicDerivativeBlock& block, double* value,
                                const std::array<double*, kNumShapeDerivatives>& derivative, bool overwrite) {
  using L = Lanes<T>;
  constexpr int W = L::size;
  const SuperOffsets off(supersample, grid.step);
  const DerivativeForms forms(block, supersample);
  const T lane_x = L::iota() * T(grid.step);
  auto emit = [&](auto s, std::ptrdiff_t k) {
    using U = decltype(s.v);
    using M = Lanes<U>;
    if (value) M::store(value + k, s.v * U(forms.mean));
    const U terms[kNumShapeDerivatives] = {s.sx, s.sy, s.s1, s.s2, s.sr};
    for (int p = 0; p < kNumShapeDerivatives; ++p)
      M::store(derivative[p] + k, overwrite ? terms[p] : M::load(derivative[p] + k) + terms[p]);
  };
  if (SupersampledBlock::fits(region, supersample)) {
    const SupersampledBlock sb(grid, region, off, block.shape.x0, block.shape.y0);
    std::array<std::array<double, kMaxBlockSubpixels>, 6> sums;
    int s = 0;
    for (; s + W <= sb.subpixels; s += W) {
      const T cx = L::load(&sb.cx[s]), cy = L::load(&sb.cy[s]);
      // Even and odd points in two sets of sums: two independent chains in flight.
      DerivativeSums<T> acc = DerivativeSums<T>::zero(), odd = acc;
      int k = 0;
      for (; k + 2 <= sb.points; k += 2) {
        add_derivative_terms<T, R>(cx + T(sb.px[k]), cy + T(sb.py[k]), forms, acc);
        add_derivative_terms<T, R>(cx + T(sb.px[k + 1]), cy + T(sb.py[k + 1]), forms, odd);
      }
      if (k < sb.points) add_derivative_terms<T, R>(cx + T(sb.px[k]), cy + T(sb.py[k]), forms, acc);
      acc.v += odd.v;
      acc.sx += odd.sx;
      acc.sy += odd.sy;
      acc.s1 += odd.s1;
      acc.s2 += odd.s2;
      acc.sr += odd.sr;
      int q = 0;
      for (const T& sum : {acc.v, acc.sx, acc.sy, acc.s1, acc.s2, acc.sr}) L::store(&sums[q++][s], sum);
    }
    for (; s < sb.subpixels; ++s) {  // vectorised over points
      const T cx(sb.cx[s]), cy(sb.cy[s]);
      DerivativeSums<T> acc = DerivativeSums<T>::zero();
      int k = 0;
      for (; k + W <= sb.points; k += W)
        add_derivative_terms<T, R>(cx + L::load(&sb.px[k]), cy + L::load(&sb.py[k]), forms, acc);
      DerivativeSums<double> tail{L::sum(acc.v), L::sum(acc.sx), L::sum(acc.sy), L::sum(acc.s1), L::sum(acc.s2), L::sum(acc.sr)};
      for (; k < sb.points; ++k) add_derivative_terms<double, R>(sb.cx[s] + sb.px[k], sb.cy[s] + sb.py[k], forms, tail);
      int q = 0;
      for (double sum : {tail.v, tail.sx, tail.sy, tail.s1, tail.s2, tail.sr}) sums[q++][s] = sum;
    }
    s = 0;
    for (int j = region.y_begin; j < region.y_end; ++j) {
      const std::ptrdiff_t row = static_cast<std::ptrdiff_t>(j) * grid.size;
      for (int i = region.x_begin; i < region.x_end; ++i, ++s)
        emit(DerivativeSums<double>{sums[0][s], sums[1][s], sums[2][s], sums[3][s], sums[4][s], sums[5][s]}, row + i);
    }
    return;
  }
  for (int j = region.y_begin; j < region.y_end; ++j) {
    const double yc = grid.origin + grid.step * j - block.shape.y0;
    const std::ptrdiff_t row = static_cast<std::ptrdiff_t>(j) * grid.size;
    int i = region.x_begin;
    if (off.n == 1) {  // one sample per sub-pixel (all but the central block): two vectors at a time
      const T dy(yc);
      for (; i + 2 * W <= region.x_end; i += 2 * W) {
        const T xc0 = T(grid.origin + grid.step * i - block.shape.x0) + lane_x;
        const T xc1 = T(grid.origin + grid.step * (i + W) - block.shape.x0) + lane_x;
        DerivativeSums<T> s0 = DerivativeSums<T>::zero(), s1 = s0;
        add_derivative_terms<T, R>(xc0, dy, forms, s0);
        add_derivative_terms<T, R>(xc1, dy, forms, s1);
        emit(s0, row + i);
        emit(s1, row + i + W);
      }
    }
    for (; i + W <= region.x_end; i += W) {
      const T xc = T(grid.origin + grid.step * i - block.shape.x0) + lane_x;
      emit(derivative_sums<T, R>(xc, yc, off, forms), row + i);
    }
    for (; i < region.x_end; ++i) {
      const double xc = grid.origin + grid.step * i - block.shape.x0;
      emit(derivative_sums<double, R>(xc, yc, off, forms), row + i);
    }
  }
}

// The dispatch table entry for lane type T.
template <class T>
ProfileKernels make_profile_kernels(const char* name) {
  ProfileKernels k;
  k.name = name;
  k.lanes = Lanes<T>::size;
  k.accumulate_value = [](const SubpixelGrid& g, const GridRegion& r, int ss, const SersicBlock& b, double amp,
                          double* out) {
    switch (b.root) {
      case SersicRoot::kSquareRoot: return accumulate_value_rows<T, SersicRoot::kSquareRoot>(g, r, ss, b, amp, out);
      case SersicRoot::kEighthRoot: return accumulate_value_rows<T, SersicRoot::kEighthRoot>(g, r, ss, b, amp, out);
      case SersicRoot::kGeneralPow: return accumulate_value_rows<T, SersicRoot::kGeneralPow>(g, r, ss, b, amp, out);
    }
  };
  k.accumulate_derivatives = [](const SubpixelGrid& g, const GridRegion& r, int ss, const SersicDerivativeBlock& b,
                                double* value, const std::array<double*, kNumShapeDerivatives>& d, bool overwrite) {
    switch (b.shape.root) {
      case SersicRoot::kSquareRoot:
        return accumulate_derivative_rows<T, SersicRoot::kSquareRoot>(g, r, ss, b, value, d, overwrite);
      case SersicRoot::kEighthRoot:
        return accumulate_derivative_rows<T, SersicRoot::kEighthRoot>(g, r, ss, b, value, d, overwrite);
      case SersicRoot::kGeneralPow:
        return accumulate_derivative_rows<T, SersicRoot::kGeneralPow>(g, r, ss, b, value, d, overwrite);
    }
  };
  return k;
}

}  // namespace
}  // namespace stampede::kernels
