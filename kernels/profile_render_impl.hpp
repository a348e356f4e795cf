// The Sérsic sub-pixel kernels written once over a lane type T: `double` (the scalar reference) or
// xsimd::batch<double, Arch>. Included only by the per-ISA translation units
// (profile_render_<isa>.cpp), each compiled with its instruction set's flags; never by headers.
// Everything here has internal linkage, so no inline function compiled for one ISA can be picked
// by the linker for another.
#pragma once

#include <xsimd/xsimd.hpp>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstddef>

#include "kernels/profile_render.hpp"

namespace stampede::kernels {
namespace {

template <class T>
struct Lanes {  // the scalar reference
  static constexpr int size = 1;
  static T load(const double* p) { return *p; }
  static void store(double* p, T v) { *p = v; }
  static T iota() { return 0.0; }
  static T select(bool c, T a, T b) { return c ? a : b; }
  static T max(T a, T b) { return std::max(a, b); }
  static T exp(T x) { return std::exp(x); }
  static T sqrt(T x) { return std::sqrt(x); }
  static T pow(T x, double y) { return std::pow(x, y); }
  static double sum(T x) { return x; }
};

template <class A>
struct Lanes<xsimd::batch<double, A>> {
  using B = xsimd::batch<double, A>;
  static constexpr int size = static_cast<int>(B::size);
  static B load(const double* p) { return B::load_unaligned(p); }
  static void store(double* p, B v) { v.store_unaligned(p); }
  static B iota() {
    alignas(64) double v[B::size];
    for (std::size_t k = 0; k < B::size; ++k) v[k] = static_cast<double>(k);
    return B::load_aligned(v);
  }
  static B select(xsimd::batch_bool<double, A> c, B a, B b) { return xsimd::select(c, a, b); }
  static B max(B a, B b) { return xsimd::max(a, b); }
  static B exp(B x) { return xsimd::exp(x); }
  static B sqrt(B x) { return xsimd::sqrt(x); }
  static B pow(B x, double y) { return xsimd::pow(x, B(y)); }
  static double sum(B x) { return xsimd::hadd(x); }
};

template <class T, SersicRoot R>
inline T root_of(T u, double inv_2n) {
  using L = Lanes<T>;
  if constexpr (R == SersicRoot::kSquareRoot) {
    return L::sqrt(u);
  } else if constexpr (R == SersicRoot::kEighthRoot) {
    return L::sqrt(L::sqrt(L::sqrt(u)));  // no pow for n = 4
  } else {
    return L::pow(u, inv_2n);
  }
}

struct SuperOffsets {
  std::array<double, 64> d{};
  int n = 1;
  SuperOffsets(int supersample, double step) : n(supersample) {
    for (int a = 0; a < n; ++a) d[a] = step * ((a + 0.5) / n - 0.5);
  }
};

// The profile at offsets (dx, dy) from the centre (one per lane).
template <class T, SersicRoot R>
inline T value_at(T dx, T dy, const SersicBlock& block) {
  using L = Lanes<T>;
  const EllipseQuadratic q = block.q;
  const T u = (T(q.xx) * dx + T(2.0 * q.xy) * dy) * dx + T(q.yy) * dy * dy;
  return L::exp(T(-block.b) * root_of<T, R>(L::max(u, T(block.u_floor)), block.inv_2n));
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
struct DerivativeSums {
  T v = T(0.0), sx = T(0.0), sy = T(0.0), s1 = T(0.0), s2 = T(0.0), sr = T(0.0);
};

// Adds the value and gradient terms at offsets (dx, dy) from the centre (one per lane).
template <class T, SersicRoot R>
inline void add_derivative_terms(T dx, T dy, const SersicDerivativeBlock& block, DerivativeSums<T>& s) {
  using L = Lanes<T>;
  const EllipseQuadratic q = block.shape.q, q1 = block.dq_de1, q2 = block.dq_de2;
  const double b = block.shape.b, inv_2n = block.shape.inv_2n;
  const T u_floor(block.shape.u_floor), zero(0.0);
  // d value / du = -b value (du^(1/2n)/du) = -b value t inv_2n / u; the amplitude folds in here.
  const T g_scale(-block.amplitude * b * inv_2n);
  const T u_raw = (T(q.xx) * dx + T(2.0 * q.xy) * dy) * dx + T(q.yy) * dy * dy;
  const T u = L::max(u_raw, u_floor);
  const T t = root_of<T, R>(u, inv_2n);
  const T v = L::exp(T(-b) * t);
  // The gradient is singular at u = 0 (measure zero): 0 there. Under the floor the value
  // depends only on r (through u_floor), not on position or shape.
  const T g = L::select(u > zero, g_scale * v * t / L::max(u, T(1e-300)), zero);
  const T gs = L::select(u_raw >= u_floor, g, zero);
  s.v += v;
  s.sx += gs * (T(q.xx) * dx + T(q.xy) * dy);
  s.sy += gs * (T(q.xy) * dx + T(q.yy) * dy);
  s.s1 += gs * ((T(q1.xx) * dx + T(2.0 * q1.xy) * dy) * dx + T(q1.yy) * dy * dy);
  s.s2 += gs * ((T(q2.xx) * dx + T(2.0 * q2.xy) * dy) * dx + T(q2.yy) * dy * dy);
  s.sr += g * u;
}

template <class T, SersicRoot R>
inline DerivativeSums<T> derivative_sums(T xc, double yc, const SuperOffsets& off, const SersicDerivativeBlock& block) {
  DerivativeSums<T> s;
  for (int bb = 0; bb < off.n; ++bb) {
    const T dy(yc + off.d[bb]);
    for (int a = 0; a < off.n; ++a) add_derivative_terms<T, R>(xc + T(off.d[a]), dy, block, s);
  }
  return s;
}

// The supersampling points of one sub-pixel as flat offset lists, so that a region narrower than a
// vector (the N_u x N_u central block) is vectorised over its U2 x U2 points instead.
struct PointOffsets {
  std::array<double, 64 * 64> x{}, y{};
  int count = 0;
  explicit PointOffsets(const SuperOffsets& off) : count(off.n * off.n) {
    for (int k = 0; k < count; ++k) {
      x[static_cast<std::size_t>(k)] = off.d[static_cast<std::size_t>(k % off.n)];
      y[static_cast<std::size_t>(k)] = off.d[static_cast<std::size_t>(k / off.n)];
    }
  }
};

template <class T, SersicRoot R>
double point_value_sum(double xc, double yc, const PointOffsets& p, const SersicBlock& block) {
  using L = Lanes<T>;
  constexpr int W = L::size;
  T acc(0.0);
  int k = 0;
  for (; k + W <= p.count; k += W) acc += value_at<T, R>(T(xc) + L::load(&p.x[k]), T(yc) + L::load(&p.y[k]), block);
  double sum = L::sum(acc);
  for (; k < p.count; ++k) sum += value_at<double, R>(xc + p.x[k], yc + p.y[k], block);
  return sum;
}

template <class T, SersicRoot R>
DerivativeSums<double> point_derivative_sums(double xc, double yc, const PointOffsets& p,
                                             const SersicDerivativeBlock& block) {
  using L = Lanes<T>;
  constexpr int W = L::size;
  DerivativeSums<T> acc;
  int k = 0;
  for (; k + W <= p.count; k += W)
    add_derivative_terms<T, R>(T(xc) + L::load(&p.x[k]), T(yc) + L::load(&p.y[k]), block, acc);
  DerivativeSums<double> s;
  s.v = L::sum(acc.v);
  s.sx = L::sum(acc.sx);
  s.sy = L::sum(acc.sy);
  s.s1 = L::sum(acc.s1);
  s.s2 = L::sum(acc.s2);
  s.sr = L::sum(acc.sr);
  for (; k < p.count; ++k) add_derivative_terms<double, R>(xc + p.x[k], yc + p.y[k], block, s);
  return s;
}

// A region is vectorised over points when its rows are narrower than a vector and each sub-pixel
// has at least a vector's worth of points.
template <class T>
bool vectorise_over_points(const GridRegion& region, int supersample) {
  constexpr int W = Lanes<T>::size;
  return W > 1 && region.x_end - region.x_begin < W && supersample * supersample >= W;
}

template <class T, SersicRoot R>
void accumulate_value_rows(const SubpixelGrid& grid, const GridRegion& region, int supersample,
                           const SersicBlock& block, double amplitude, double* out) {
  using L = Lanes<T>;
  constexpr int W = L::size;
  const SuperOffsets off(supersample, grid.step);
  const double scale = amplitude / (off.n * off.n);
  const T lane_x = L::iota() * T(grid.step);
  if (vectorise_over_points<T>(region, supersample)) {
    const PointOffsets points(off);
    for (int j = region.y_begin; j < region.y_end; ++j) {
      const double yc = grid.origin + grid.step * j - block.y0;
      double* row = out + static_cast<std::ptrdiff_t>(j) * grid.size;
      for (int i = region.x_begin; i < region.x_end; ++i)
        row[i] += scale * point_value_sum<T, R>(grid.origin + grid.step * i - block.x0, yc, points, block);
    }
    return;
  }
  for (int j = region.y_begin; j < region.y_end; ++j) {
    const double yc = grid.origin + grid.step * j - block.y0;
    double* row = out + static_cast<std::ptrdiff_t>(j) * grid.size;
    int i = region.x_begin;
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
  const double mean = 1.0 / (off.n * off.n);
  const T lane_x = L::iota() * T(grid.step);
  // du/dx0 = -2 (xx dx + xy dy), du/dy0 = -2 (xy dx + yy dy).
  const double cx = -2.0 * mean, cr = block.du_dr_over_u * mean;
  auto emit = [&](auto s, std::ptrdiff_t k) {
    using U = decltype(s.v);
    using M = Lanes<U>;
    if (value) M::store(value + k, s.v * U(mean));
    const U terms[kNumShapeDerivatives] = {s.sx * U(cx), s.sy * U(cx), s.s1 * U(mean), s.s2 * U(mean), s.sr * U(cr)};
    for (int p = 0; p < kNumShapeDerivatives; ++p)
      M::store(derivative[p] + k, overwrite ? terms[p] : M::load(derivative[p] + k) + terms[p]);
  };
  if (vectorise_over_points<T>(region, supersample)) {
    const PointOffsets points(off);
    for (int j = region.y_begin; j < region.y_end; ++j) {
      const double yc = grid.origin + grid.step * j - block.shape.y0;
      const std::ptrdiff_t row = static_cast<std::ptrdiff_t>(j) * grid.size;
      for (int i = region.x_begin; i < region.x_end; ++i)
        emit(point_derivative_sums<T, R>(grid.origin + grid.step * i - block.shape.x0, yc, points, block), row + i);
    }
    return;
  }
  for (int j = region.y_begin; j < region.y_end; ++j) {
    const double yc = grid.origin + grid.step * j - block.shape.y0;
    const std::ptrdiff_t row = static_cast<std::ptrdiff_t>(j) * grid.size;
    int i = region.x_begin;
    for (; i + W <= region.x_end; i += W) {
      const T xc = T(grid.origin + grid.step * i - block.shape.x0) + lane_x;
      emit(derivative_sums<T, R>(xc, yc, off, block), row + i);
    }
    for (; i < region.x_end; ++i) {
      const double xc = grid.origin + grid.step * i - block.shape.x0;
      emit(derivative_sums<double, R>(xc, yc, off, block), row + i);
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
