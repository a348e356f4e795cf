// The exact renderer's term loop written once over a lane type T: `double` (the scalar reference)
// or xsimd::batch<double, Arch>. Included only by the per-ISA translation units
// (kspace_render_<isa>.cpp), each compiled with its instruction set's flags; never by headers.
// Everything here has internal linkage (see lanes.hpp).
#pragma once

#include <bit>
#include <cmath>
#include <cstdint>

#include "kernels/kspace_render.hpp"
#include "kernels/lanes.hpp"
#include "kernels/sersic.hpp"

namespace stampede::kernels {
namespace {

// The table's interval index (times SersicKTable::kStride), the offset u in it and 2^-octave,
// all from w's bits (w already clamped into the table's range): no logarithm.
constexpr std::uint64_t kExponentBits = 0x7FF0000000000000ULL;
constexpr std::uint64_t kMantissaBits = 0x000FFFFFFFFFFFFFULL;
constexpr std::uint64_t kOneBits = 0x3FF0000000000000ULL;
constexpr std::uint64_t kInverseBits = 0x7FE0000000000000ULL;  // bits(2^-e) = this - exponent bits of 2^e

struct TableIndexScalar {
  std::int64_t i;
  double u, inv_octave;
};
inline TableIndexScalar table_index(const SersicKTable& tab, double w) {
  const std::uint64_t bits = std::bit_cast<std::uint64_t>(w);
  const std::int64_t i = static_cast<std::int64_t>(bits >> SersicKTable::kIndexShift) - tab.index_base;
  return {i * SersicKTable::kStride,
          std::bit_cast<double>(((bits << SersicKTable::kSubdivisionBits) & kMantissaBits) | kOneBits) - 1.0,
          std::bit_cast<double>(kInverseBits - (bits & kExponentBits))};
}
template <class A>
struct TableIndexBatch {
  xsimd::batch<std::int64_t, A> i;
  xsimd::batch<double, A> u, inv_octave;
};
template <class A>
inline TableIndexBatch<A> table_index(const SersicKTable& tab, xsimd::batch<double, A> w) {
  using U = xsimd::batch<std::uint64_t, A>;
  using I = xsimd::batch<std::int64_t, A>;
  using B = xsimd::batch<double, A>;
  const U bits = xsimd::bitwise_cast<U>(w);
  const U i = ((bits >> SersicKTable::kIndexShift) - U(static_cast<std::uint64_t>(tab.index_base))) << 3;
  static_assert(SersicKTable::kStride == 8);
  const B u = xsimd::bitwise_cast<B>(((bits << SersicKTable::kSubdivisionBits) & U(kMantissaBits)) | U(kOneBits)) - B(1.0);
  const B inv = xsimd::bitwise_cast<B>(U(kInverseBits) - (bits & U(kExponentBits)));
  return {xsimd::bitwise_cast<I>(i), u, inv};
}

inline double gather(const double* p, std::int64_t i) { return p[i]; }
template <class A>
inline xsimd::batch<double, A> gather(const double* p, xsimd::batch<std::int64_t, A> i) {
  return xsimd::batch<double, A>::gather(p, i);
}

inline double klog(double x) { return std::log(x); }
template <class A>
inline xsimd::batch<double, A> klog(xsimd::batch<double, A> x) {
  return xsimd::log(x);
}

template <class T>
struct Transform {
  T value, slope;  // F and dF/dw
};

// F(w) and dF/dw from the table: the interval's polynomial in u and its derivative (Horner), with
// the small-w series and the power-law tail selected lane by lane.
template <class T, bool kSlope>
inline Transform<T> tabulated(const SersicKTable& tab, T w) {
  using L = Lanes<T>;
  const T ws = L::min(L::max(w, T(tab.w_lo)), T(tab.w_last));
  const auto [i, u, inv_octave] = table_index(tab, ws);
  const double* c = tab.coefficients.data();
  const T c5 = gather(c + 5, i), c4 = gather(c + 4, i), c3 = gather(c + 3, i);
  const T c2 = gather(c + 2, i), c1 = gather(c + 1, i), c0 = gather(c, i);
  T value = ((((c5 * u + c4) * u + c3) * u + c2) * u + c1) * u + c0;
  T slope(0.0);
  if constexpr (kSlope) {
    const T dp = (((T(5.0) * c5 * u + T(4.0) * c4) * u + T(3.0) * c3) * u + T(2.0) * c2) * u + c1;
    slope = dp * (T(double(SersicKTable::kSubdivisions)) * inv_octave);
  }
  const auto small = w < T(tab.w_lo);
  value = L::select(small, T(1.0) - T(tab.c2) * w, value);
  if constexpr (kSlope) slope = L::select(small, T(-tab.c2), slope);
  const auto tail = w >= T(tab.w_hi);
  if (L::any(tail)) {
    const T wt = L::max(w, T(tab.w_hi));
    const T tv = T(tab.tail_value) * L::exp(T(0.5 * tab.tail_slope) * (klog(wt) - T(tab.log_w_hi)));
    value = L::select(tail, tv, value);
    if constexpr (kSlope) slope = L::select(tail, tv * T(0.5 * tab.tail_slope) / wt, slope);
  }
  return {value, slope};
}

// The exponential disc in closed form: F = (1 + w / b1^2)^(-3/2), dF/dw = -3/2 F / (b1^2 + w).
template <class T, bool kSlope>
inline Transform<T> exponential(T w, double inv_b2) {
  using L = Lanes<T>;
  const T t = T(1.0) + w * T(inv_b2);
  if constexpr (L::kEstimatedRsqrt) {  // no division or square root where the hardware estimates 1/sqrt
    const T r = L::rsqrt(t), r2 = r * r;
    const T value = r2 * r;
    T slope(0.0);
    if constexpr (kSlope) slope = T(-1.5 * inv_b2) * value * r2;
    return {value, slope};
  } else {
    const T value = T(1.0) / (t * L::sqrt(t));
    T slope(0.0);
    if constexpr (kSlope) slope = T(-1.5 * inv_b2) * value / t;
    return {value, slope};
  }
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

// What a pass accumulates: the model; the two component images per unit amplitude; or those and
// the five shape derivatives (the KSpaceImage order).
enum class Pass { kModel, kComponents, kJacobian };
constexpr int pass_outputs(Pass p) { return p == Pass::kModel ? 1 : p == Pass::kComponents ? 2 : kNumKSpaceImages; }

// One spectrum block's W lanes at sub-vector offset `lane0`: the sums over its alias entries, each
// term a real weight times its alias's phase, then the bin's phase once.
template <class T, bool kBulgeTable, bool kDiscTable, Pass kPass>
inline void block_lanes(const KSpaceTerms& terms, const KSpaceModel& m, int block, int lane0, double inv_b2,
                        const KSpaceSpectra& out) {
  using L = Lanes<T>;
  constexpr int kOut = pass_outputs(kPass);
  constexpr bool kJacobian = kPass == Pass::kJacobian;
  Complex<T> acc[kOut];
  for (int k = 0; k < kOut; ++k) acc[k] = {T(0.0), T(0.0)};
  const KSpaceComponent& cb = m.bulge;
  const KSpaceComponent& cd = m.disc;
  for (std::int32_t e = terms.block_begin[block]; e < terms.block_begin[block + 1]; ++e) {
    const std::int32_t ix = terms.entry_ix[e] + lane0, iy = terms.entry_iy[e], a = terms.entry_alias[e];
    const T kx = L::load(terms.kx_values.data() + ix);
    const T ky(terms.ky_values[iy]);
    const T kxx = kx * kx, kxy = kx * ky, kyy = ky * ky;
    const T ppi = L::load(terms.ppi.data() + static_cast<std::size_t>(e) * kKBlock + lane0);
    const T cr(m.alias_phase_re[a]), ci(m.alias_phase_im[a]);
    const T wb = form(cb.wxx, cb.wxy, cb.wyy, kxx, kxy, kyy);
    const T wd = form(cd.wxx, cd.wxy, cd.wyy, kxx, kxy, kyy);
    const Transform<T> fb = component_transform<T, kBulgeTable, kJacobian>(cb, wb, inv_b2);
    const Transform<T> fd = component_transform<T, kDiscTable, kJacobian>(cd, wd, inv_b2);
    auto add = [&](int k, T weight) {
      acc[k].re += weight * cr;
      acc[k].im += weight * ci;
    };
    if constexpr (kPass == Pass::kModel) {
      add(0, (T(cb.flux) * fb.value + T(cd.flux) * fd.value) * ppi);
    } else if constexpr (kPass == Pass::kComponents) {  // the Jacobian pass's expressions
      const T vb = fb.value * ppi, vd = fd.value * ppi;
      add(kKBulge, T(cb.flux_per_amplitude) * vb);
      add(kKDisc, T(cd.flux_per_amplitude) * vd);
    } else {
      const T vb = fb.value * ppi, vd = fd.value * ppi;
      add(kKBulge, T(cb.flux_per_amplitude) * vb);
      add(kKDisc, T(cd.flux_per_amplitude) * vd);
      const T g = T(cb.flux) * vb + T(cd.flux) * vd;  // the model's real weight
      add(kKX0, g * kx);  // times -i below: d/dx0 of e^{-i kx x0}
      add(kKY0, g * ky);
      const T sb = T(cb.flux) * fb.slope * ppi, sd = T(cd.flux) * fd.slope * ppi;
      add(kKE1, sb * form(cb.e1xx, cb.e1xy, cb.e1yy, kxx, kxy, kyy) + sd * form(cd.e1xx, cd.e1xy, cd.e1yy, kxx, kxy, kyy));
      add(kKE2, sb * form(cb.e2xx, cb.e2xy, cb.e2yy, kxx, kxy, kyy) + sd * form(cd.e2xx, cd.e2xy, cd.e2yy, kxx, kxy, kyy));
      add(kKRadius, T(2.0 * m.dlnr) * (g + sb * wb + sd * wd));
    }
  }
  const int per_row = terms.row_stride / kKBlock;
  const std::size_t row = static_cast<std::size_t>(block / per_row);
  const std::size_t col = static_cast<std::size_t>(block % per_row) * kKBlock + lane0;
  const std::size_t o = row * terms.row_stride + col;
  // The bin's phase e^{-i k0.x0} (its x and y factors).
  const T bxr = L::load(m.bin_phase_x_re + col), bxi = L::load(m.bin_phase_x_im + col);
  const T byr(m.bin_phase_y_re[row]), byi(m.bin_phase_y_im[row]);
  const T pr = bxr * byr - bxi * byi, pi = bxr * byi + bxi * byr;
  for (int k = 0; k < kOut; ++k) {
    T re = acc[k].re * pr - acc[k].im * pi, im = acc[k].re * pi + acc[k].im * pr;
    if (kJacobian && (k == kKX0 || k == kKY0)) {  // -i (re + i im) = im - i re
      const T t = re;
      re = im;
      im = -t;
    }
    L::store(out.re[k] + o, re);
    L::store(out.im[k] + o, im);
  }
}

template <class T, bool kBulgeTable, bool kDiscTable, Pass kPass>
void accumulate_blocks(const KSpaceTerms& terms, const KSpaceModel& m, const KSpaceSpectra& out) {
  constexpr int W = Lanes<T>::size;
  static_assert(kKBlock % W == 0);
  const double b1 = sersic_b(1.0), inv_b2 = 1.0 / (b1 * b1);
  const int blocks = terms.blocks();
  for (int b = 0; b < blocks; ++b)
    for (int lane0 = 0; lane0 < kKBlock; lane0 += W) block_lanes<T, kBulgeTable, kDiscTable, kPass>(terms, m, b, lane0, inv_b2, out);
}

// Chooses the instantiation for the components' kinds, once per call.
template <class T, Pass kPass>
void accumulate(const KSpaceTerms& terms, const KSpaceModel& m, const KSpaceSpectra& out) {
  const bool bt = m.bulge.table != nullptr, dt = m.disc.table != nullptr;
  if (bt && !dt) return accumulate_blocks<T, true, false, kPass>(terms, m, out);
  if (bt && dt) return accumulate_blocks<T, true, true, kPass>(terms, m, out);
  if (!bt && dt) return accumulate_blocks<T, false, true, kPass>(terms, m, out);
  return accumulate_blocks<T, false, false, kPass>(terms, m, out);
}

template <class T>
KSpaceKernels make_kspace_kernels(const char* name) {
  KSpaceKernels k;
  k.name = name;
  k.lanes = Lanes<T>::size;
  k.accumulate_model = accumulate<T, Pass::kModel>;
  k.accumulate_components = accumulate<T, Pass::kComponents>;
  k.accumulate_jacobian = accumulate<T, Pass::kJacobian>;
  return k;
}

}  // namespace
}  // namespace stampede::kernels
