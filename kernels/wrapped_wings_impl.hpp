// The copies' far-wing light (wrapped_wings.hpp) written once over a lane type T: `double` (the
// scalar reference) or xsimd::batch<double, Arch>, one lane per evaluation point. Included only by
// the per-ISA translation units (wrapped_wings_<isa>.cpp); never by headers.
#pragma once

#include <algorithm>
#include <array>
#include <cmath>

#include "kernels/lanes.hpp"
#include "kernels/wrapped_wings.hpp"

namespace stampede::kernels {
namespace {

template <class T>
inline T wing_root(const WingComponent& c, T u) {
  using L = Lanes<T>;
  switch (c.root) {
    case SersicRoot::kSquareRoot: return L::sqrt(u);
    case SersicRoot::kEighthRoot: return L::sqrt(L::sqrt(L::sqrt(u)));
    case SersicRoot::kGeneralPow: break;
  }
  return L::pow(u, c.s);
}

// One copy at offset (ox, oy) seen from points (x, y): the blurred far wing and, with kDerivatives,
// its five derivatives added to d[].
//
// I(u) = exp(phi), phi = -b u^s, and the blur's second-order term over I, in log form:
//   B = 1/2 M : grad grad I / I = 1/2 (phi'' + phi'^2) G + phi' T,
// G = grad u^T M grad u, T = tr(M Q) (grad grad u = 2 Q). The value is I e^B rather than I (1 + B):
// the same to second order, and exact for an exponential wing under a Gaussian blur (1 + B misses
// part of the blur's effect on a disc's far wing: docs/performance.md, "The exact renderer's
// constants"). Where the profile is steep on the blur's scale (across a thin disc's minor axis) B
// grows without bound and the expansion means nothing (a Moffat's power-law wing against an
// exponential has no such moment), so B is saturated smoothly: B / sqrt(1 + B^2 / 6) =
// B (1 - B^2 / 12 ...), below sqrt(6).
template <class T, bool kDerivatives>
inline T copy_wing(const WingComponent& c, const BlurMoments& m, T x, T y, std::array<T, kWingDerivatives>* d) {
  using L = Lanes<T>;
  const EllipseQuadratic& q = c.q;
  const T dx = x - T(c.x0), dy = y - T(c.y0);
  const T vx = T(q.xx) * dx + T(q.xy) * dy, vy = T(q.xy) * dx + T(q.yy) * dy;  // Q d: grad u = 2 Q d
  // Copies never come near their centre (u >= (N - stamp)^2 / r^2): u > 0 in every lane used.
  const T u = L::max(dx * vx + dy * vy, T(1e-300));
  const T mvx = T(m.xx) * vx + T(m.xy) * vy, mvy = T(m.xy) * vx + T(m.yy) * vy;
  const T g = T(4.0) * (vx * mvx + vy * mvy);
  const double t = m.xx * q.xx + 2 * m.xy * q.xy + m.yy * q.yy;
  const T us = wing_root(c, u);
  const T inv_u = T(1.0) / u;
  const T p1 = T(-c.b * c.s) * us * inv_u;
  const T p2 = p1 * T(c.s - 1) * inv_u;
  const T blur = T(0.5) * (p2 + p1 * p1) * g + p1 * T(t);
  const T soft = T(1.0) / L::sqrt(T(1.0) + blur * blur * T(1.0 / 6));
  const T value = L::exp(T(-c.b) * us + blur * soft);
  if constexpr (kDerivatives) {
    const T p3 = p2 * T(c.s - 2) * inv_u;
    // d value = value (phi' du + B_sat'(B) dB), dB = (B's u-derivative) du + 1/2 (phi'' + phi'^2) dG
    // + phi' dT: value (a_u du + a_g dG + a_t dT).
    const T sat = value * soft * soft * soft;
    const T a_u = value * p1 + sat * (T(0.5) * (p3 + T(2.0) * p1 * p2) * g + p2 * T(t));
    const T a_g = sat * T(0.5) * (p2 + p1 * p1), a_t = sat * p1;
    auto& o = *d;
    // Centre: d(dx)/dx0 = -1, so du = -2 (Q d)_x, dG = 8 (M Q d) . dv with dv = -Q e_x.
    o[0] += a_u * (T(-2.0) * vx) + a_g * (T(-8.0) * (mvx * T(q.xx) + mvy * T(q.xy)));
    o[1] += a_u * (T(-2.0) * vy) + a_g * (T(-8.0) * (mvx * T(q.xy) + mvy * T(q.yy)));
    auto shape = [&](const EllipseQuadratic& dq) {
      const T wx = T(dq.xx) * dx + T(dq.xy) * dy, wy = T(dq.xy) * dx + T(dq.yy) * dy;
      const T du = dx * wx + dy * wy;
      const T dg = T(8.0) * (mvx * wx + mvy * wy);
      const double dt = m.xx * dq.xx + 2 * m.xy * dq.xy + m.yy * dq.yy;
      return a_u * du + a_g * dg + a_t * T(dt);
    };
    o[2] += shape(c.dq_de1);
    o[3] += shape(c.dq_de2);
    // Radius: Q scales by (1 + kappa dr), so u, G and T do too (G twice).
    const double k = c.du_dr_over_u;
    o[4] += a_u * T(k) * u + a_g * T(2 * k) * g + a_t * T(k * t);
  }
  return value;
}

template <class T, bool kDerivatives>
void add_wings_lanes(const WingComponent& c, const BlurMoments& m, const CopyOffset* copies, int ncopies,
                     const double* x, const double* y, int begin, double value_scale, double* value,
                     double derivative_scale, double* const* derivative) {
  using L = Lanes<T>;
  const T px = L::load(x + begin), py = L::load(y + begin);
  T sum(0.0);
  std::array<T, kWingDerivatives> d;
  d.fill(T(0.0));
  for (int k = 0; k < ncopies; ++k)
    sum += copy_wing<T, kDerivatives>(c, m, px - T(copies[k].dx), py - T(copies[k].dy), &d);
  if (value) L::store(value + begin, L::load(value + begin) + T(value_scale) * sum);
  if constexpr (kDerivatives)
    for (int k = 0; k < kWingDerivatives; ++k)
      L::store(derivative[k] + begin, L::load(derivative[k] + begin) + T(derivative_scale) * d[k]);
}

template <class T>
void add_wings(const WingComponent& c, const BlurMoments& m, const CopyOffset* copies, int ncopies, const double* x,
               const double* y, int count, double value_scale, double* value, double derivative_scale,
               double* const* derivative) {
  constexpr int W = Lanes<T>::size;
  int i = 0;
  for (; i + W <= count; i += W) {
    if (derivative)
      add_wings_lanes<T, true>(c, m, copies, ncopies, x, y, i, value_scale, value, derivative_scale, derivative);
    else
      add_wings_lanes<T, false>(c, m, copies, ncopies, x, y, i, value_scale, value, derivative_scale, derivative);
  }
  for (; i < count; ++i) {  // the tail, one point at a time
    if (derivative)
      add_wings_lanes<double, true>(c, m, copies, ncopies, x, y, i, value_scale, value, derivative_scale, derivative);
    else
      add_wings_lanes<double, false>(c, m, copies, ncopies, x, y, i, value_scale, value, derivative_scale, derivative);
  }
}

// out[y][x] += sum_jy basis[y][jy] sum_jx values[jy][jx] basis[x][jx], vectorised along x
// (basis_t[j][x] = basis[x][j]); scratch holds nodes x size.
template <class T>
void interpolate(int size, int nodes, const double* basis, const double* basis_t, const double* values, double* out,
                 double* scratch) {
  using L = Lanes<T>;
  constexpr int W = L::size;
  auto row_axpy = [&](double a, const double* src, double* dst) {  // dst[0..size) += a src
    int x = 0;
    for (; x + W <= size; x += W) L::store(dst + x, L::load(dst + x) + T(a) * L::load(src + x));
    for (; x < size; ++x) dst[x] += a * src[x];
  };
  for (int jy = 0; jy < nodes; ++jy) {
    double* s = scratch + static_cast<std::size_t>(jy) * size;
    std::fill_n(s, size, 0.0);
    for (int jx = 0; jx < nodes; ++jx) row_axpy(values[jy * nodes + jx], basis_t + static_cast<std::size_t>(jx) * size, s);
  }
  for (int y = 0; y < size; ++y) {
    double* o = out + static_cast<std::size_t>(y) * size;
    for (int jy = 0; jy < nodes; ++jy) row_axpy(basis[y * nodes + jy], scratch + static_cast<std::size_t>(jy) * size, o);
  }
}

template <class T>
WrapKernels make_wrap_kernels(const char* name) {
  WrapKernels k;
  k.name = name;
  k.lanes = Lanes<T>::size;
  k.add_wings = add_wings<T>;
  k.interpolate = interpolate<T>;
  return k;
}

}  // namespace
}  // namespace stampede::kernels
