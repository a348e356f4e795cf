// The exact renderer's term loop written once over a lane type T: `double` (the scalar reference)
// or xsimd::batch<double, Arch>. Included only by the per-ISA translation units
// (kspace_render_<isa>.cpp), each compiled with its instruction set's flags; never by headers.
// Everything here has internal linkage (see lanes.hpp).
#pragma once

#include <cmath>
#include <cstdint>

#include "kernels/kspace_render.hpp"
#include "kernels/lanes.hpp"
#include "kernels/sersic.hpp"

namespace stampede::kernels {
namespace {

// The operations this loop needs beyond lanes.hpp: log, the table index and its gather.
inline double klog(double x) { return std::log(x); }
template <class A>
inline xsimd::batch<double, A> klog(xsimd::batch<double, A> x) {
  return xsimd::log(x);
}

// Interval index floor(t) (t already clamped to [0, intervals)), and its offset u = t - floor(t).
struct IndexScalar {
  std::int64_t i;
  double u;
};
inline IndexScalar split_index(double t) {
  const double f = std::floor(t);
  return {static_cast<std::int64_t>(f), t - f};
}
template <class A>
struct IndexBatch {
  xsimd::batch<std::int64_t, A> i;
  xsimd::batch<double, A> u;
};
template <class A>
inline IndexBatch<A> split_index(xsimd::batch<double, A> t) {
  using B = xsimd::batch<double, A>;
  using I = xsimd::batch<std::int64_t, A>;
  const B f = xsimd::floor(t);
  // 0 <= f < 2^52: f + 2^52 holds f in its mantissa bits (AVX2 has no double -> int64 convert,
  // xsimd's to_int goes through memory there).
  const B magic(0x1p52);
  return {xsimd::bitwise_cast<I>(f + magic) - xsimd::bitwise_cast<I>(magic), t - f};
}

inline double gather(const double* p, std::int64_t i) { return p[i]; }
template <class A>
inline xsimd::batch<double, A> gather(const double* p, xsimd::batch<std::int64_t, A> i) {
  return xsimd::batch<double, A>::gather(p, i);
}

template <class T>
struct Transform {
  T value, slope;  // F and dF/dw
};

// F(w) and dF/dw from the table: the interval's polynomial and its derivative (Horner), with the
// small-q series and the power-law tail selected lane by lane.
template <class T, bool kSlope>
inline Transform<T> tabulated(const SersicKTable& tab, T w) {
  using L = Lanes<T>;
  const T ws = L::max(w, T(tab.w_min));  // log stays finite at k = 0
  const T half_log_w = T(0.5) * klog(ws);
  T t = (half_log_w - T(tab.log_q_min)) * T(tab.inv_step);
  t = L::max(T(0.0), t);
  t = L::select(t < T(tab.intervals), t, T(tab.intervals - 1));
  const auto [i, u] = split_index(t);
  const auto& c = tab.coefficients;
  const T c5 = gather(c[5].data(), i), c4 = gather(c[4].data(), i), c3 = gather(c[3].data(), i);
  const T c2 = gather(c[2].data(), i), c1 = gather(c[1].data(), i), c0 = gather(c[0].data(), i);
  T value = ((((c5 * u + c4) * u + c3) * u + c2) * u + c1) * u + c0;
  T slope(0.0);
  if constexpr (kSlope) {
    const T dp = (((T(5.0) * c5 * u + T(4.0) * c4) * u + T(3.0) * c3) * u + T(2.0) * c2) * u + c1;
    slope = dp * T(0.5 * tab.inv_step) / ws;
  }
  const auto small = w < T(tab.w_min);
  value = L::select(small, T(1.0) - T(tab.c2) * w, value);
  if constexpr (kSlope) slope = L::select(small, T(-tab.c2), slope);
  const auto tail = w >= T(tab.w_max);
  if (L::any(tail)) {
    const T tv = T(tab.tail_value) * L::exp(T(tab.tail_slope) * L::max(half_log_w - T(tab.log_q_max), T(0.0)));
    value = L::select(tail, tv, value);
    if constexpr (kSlope) slope = L::select(tail, tv * T(0.5 * tab.tail_slope) / ws, slope);
  }
  return {value, slope};
}

// The exponential disc in closed form: F = (1 + w / b1^2)^(-3/2), dF/dw = -3/2 F / (b1^2 + w).
template <class T, bool kSlope>
inline Transform<T> exponential(T w, double inv_b2) {
  using L = Lanes<T>;
  const T t = T(1.0) + w * T(inv_b2);
  const T value = T(1.0) / (t * L::sqrt(t));
  T slope(0.0);
  if constexpr (kSlope) slope = T(-1.5 * inv_b2) * value / t;
  return {value, slope};
}

template <class T, bool kTable, bool kSlope>
inline Transform<T> component_transform(const KSpaceComponent& c, T w, double inv_b2) {
  if constexpr (kTable) {
    return tabulated<T, kSlope>(*c.table, w);
  } else {
    return exponential<T, kSlope>(w, inv_b2);
  }
}

template <class T>
inline T form(double xx, double xy, double yy, T kxx, T kxy, T kyy) {
  return T(xx) * kxx + T(2.0 * xy) * kxy + T(yy) * kyy;
}

template <class T>
struct Complex {
  T re, im;
};

// One spectrum block's W lanes at sub-vector offset `lane0`: the sums over its alias entries.
template <class T, bool kBulgeTable, bool kDiscTable, bool kJacobian>
inline void block_lanes(const KSpaceTerms& terms, const KSpaceModel& m, int block, int lane0, double inv_b2,
                        const KSpaceSpectra& out) {
  using L = Lanes<T>;
  constexpr int kOut = kJacobian ? kNumKSpaceImages : 1;
  Complex<T> acc[kOut];
  for (int k = 0; k < kOut; ++k) acc[k] = {T(0.0), T(0.0)};
  const KSpaceComponent& cb = m.bulge;
  const KSpaceComponent& cd = m.disc;
  for (std::int32_t e = terms.block_begin[block]; e < terms.block_begin[block + 1]; ++e) {
    const std::int32_t ix = terms.entry_ix[e] + lane0, iy = terms.entry_iy[e];
    const T kx = L::load(terms.kx_values.data() + ix);
    const T ky(terms.ky_values[iy]);
    const T kxx = kx * kx, kxy = kx * ky, kyy = ky * ky;
    // C = PPi e^{-i k.x0}
    const T pxr = L::load(m.phase_x_re + ix), pxi = L::load(m.phase_x_im + ix);
    const T pyr(m.phase_y_re[iy]), pyi(m.phase_y_im[iy]);
    const T phr = pxr * pyr - pxi * pyi, phi = pxr * pyi + pxi * pyr;
    const std::size_t p = static_cast<std::size_t>(e) * kKBlock + lane0;
    const T ppr = L::load(terms.ppi_re.data() + p), ppi = L::load(terms.ppi_im.data() + p);
    const Complex<T> c{ppr * phr - ppi * phi, ppr * phi + ppi * phr};
    const T wb = form(cb.wxx, cb.wxy, cb.wyy, kxx, kxy, kyy);
    const T wd = form(cd.wxx, cd.wxy, cd.wyy, kxx, kxy, kyy);
    const Transform<T> fb = component_transform<T, kBulgeTable, kJacobian>(cb, wb, inv_b2);
    const Transform<T> fd = component_transform<T, kDiscTable, kJacobian>(cd, wd, inv_b2);
    const T g = T(cb.flux) * fb.value + T(cd.flux) * fd.value;
    auto add = [&](int k, T a) {
      acc[k].re += a * c.re;
      acc[k].im += a * c.im;
    };
    if constexpr (!kJacobian) {
      add(0, g);
    } else {
      add(kKBulge, T(cb.flux_per_amplitude) * fb.value);
      add(kKDisc, T(cd.flux_per_amplitude) * fd.value);
      // d/dx0 of e^{-i kx x0}: -i kx, so a C becomes (a kx) (C.im - i C.re).
      const T gx = g * kx, gy = g * ky;
      acc[kKX0].re += gx * c.im;
      acc[kKX0].im -= gx * c.re;
      acc[kKY0].re += gy * c.im;
      acc[kKY0].im -= gy * c.re;
      const T sb = T(cb.flux) * fb.slope, sd = T(cd.flux) * fd.slope;
      add(kKE1, sb * form(cb.e1xx, cb.e1xy, cb.e1yy, kxx, kxy, kyy) + sd * form(cd.e1xx, cd.e1xy, cd.e1yy, kxx, kxy, kyy));
      add(kKE2, sb * form(cb.e2xx, cb.e2xy, cb.e2yy, kxx, kxy, kyy) + sd * form(cd.e2xx, cd.e2xy, cd.e2yy, kxx, kxy, kyy));
      add(kKRadius, T(2.0 * m.dlnr) * (g + sb * wb + sd * wd));
    }
  }
  const std::size_t row = static_cast<std::size_t>(block / (terms.row_stride / kKBlock));
  const std::size_t o = row * terms.row_stride + static_cast<std::size_t>(block % (terms.row_stride / kKBlock)) * kKBlock + lane0;
  for (int k = 0; k < kOut; ++k) {
    L::store(out.re[k] + o, acc[k].re);
    L::store(out.im[k] + o, acc[k].im);
  }
}

template <class T, bool kBulgeTable, bool kDiscTable, bool kJacobian>
void accumulate_blocks(const KSpaceTerms& terms, const KSpaceModel& m, const KSpaceSpectra& out) {
  constexpr int W = Lanes<T>::size;
  static_assert(kKBlock % W == 0);
  const double b1 = sersic_b(1.0), inv_b2 = 1.0 / (b1 * b1);
  const int blocks = terms.blocks();
  for (int b = 0; b < blocks; ++b)
    for (int lane0 = 0; lane0 < kKBlock; lane0 += W) block_lanes<T, kBulgeTable, kDiscTable, kJacobian>(terms, m, b, lane0, inv_b2, out);
}

// Chooses the instantiation for the components' kinds, once per call.
template <class T, bool kJacobian>
void accumulate(const KSpaceTerms& terms, const KSpaceModel& m, const KSpaceSpectra& out) {
  const bool bt = m.bulge.table != nullptr, dt = m.disc.table != nullptr;
  if (bt && !dt) return accumulate_blocks<T, true, false, kJacobian>(terms, m, out);
  if (bt && dt) return accumulate_blocks<T, true, true, kJacobian>(terms, m, out);
  if (!bt && dt) return accumulate_blocks<T, false, true, kJacobian>(terms, m, out);
  return accumulate_blocks<T, false, false, kJacobian>(terms, m, out);
}

template <class T>
KSpaceKernels make_kspace_kernels(const char* name) {
  KSpaceKernels k;
  k.name = name;
  k.lanes = Lanes<T>::size;
  k.accumulate_model = accumulate<T, false>;
  k.accumulate_jacobian = accumulate<T, true>;
  return k;
}

}  // namespace
}  // namespace stampede::kernels
