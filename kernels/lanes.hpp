// The lane abstraction every per-instruction-set kernel is written over: `Lanes<double>` is the
// scalar reference, `Lanes<xsimd::batch<double, Arch>>` a vector of Arch's width, with the same
// operations (and vector versions of exp and rsqrt that avoid division and square roots).
// Included only by the per-ISA translation units (kernels/*_<isa>.cpp), each compiled with its
// instruction set's flags; never by headers. Everything here has internal linkage, so no inline
// function compiled for one ISA can be picked by the linker for another.
#pragma once

#include <xsimd/xsimd.hpp>

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <type_traits>

namespace stampede::kernels {
namespace {

template <class T>
struct Lanes {  // the scalar reference
  static constexpr int size = 1;
  static T load(const double* p) { return *p; }
  static void store(double* p, T v) { *p = v; }
  static T iota() { return 0.0; }
  static T select(bool c, T a, T b) { return c ? a : b; }
  static bool all(bool c) { return c; }
  static bool any(bool c) { return c; }
  static T max(T a, T b) { return std::max(a, b); }
  static T min(T a, T b) { return std::min(a, b); }
  static T exp(T x) { return std::exp(x); }
  static T sqrt(T x) { return std::sqrt(x); }
  static T pow(T x, double y) { return std::pow(x, y); }
  static constexpr bool kEstimatedRsqrt = false;
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
  static bool all(xsimd::batch_bool<double, A> c) { return xsimd::all(c); }
  static bool any(xsimd::batch_bool<double, A> c) { return xsimd::any(c); }
  static B max(B a, B b) { return xsimd::max(a, b); }
  static B min(B a, B b) { return xsimd::min(a, b); }
  // SSE4.2 has no FMA: xsimd's fma there is a multiply and an add, rounded twice.
  static constexpr bool kFusedMultiplyAdd = !std::is_same_v<A, xsimd::sse4_2>;
  // exp(x) for x <= 0 (the profiles' exp(-b t)) without division (xsimd's exp is a rational
  // approximation, and vector division is no faster per element than scalar): x = k ln2 + r,
  // |r| <= ln2/2, e^r by its degree-12 Taylor polynomial (truncation < 2e-16 relative), 2^k added
  // to the exponent bits. One-step reduction: ln2's rounding error shifts r by k 2.3e-17, a
  // relative error that matters only where e^x is far below the image's peak (with FMA). Below -708.3 it
  // returns e^-708.3 (2e-308) where libm returns a subnormal or 0.
  static B exp(B x) {
    using I = xsimd::batch<std::int64_t, A>;
    const B shift(0x1.8p52);  // adding it rounds to an integer held in the low mantissa bits
    const B xc = xsimd::max(x, B(-708.3));
    const B kd = xsimd::fma(xc, B(1.4426950408889634), shift);
    const B k = kd - shift;
    B r;
    if constexpr (kFusedMultiplyAdd) {
      r = xsimd::fnma(k, B(0.6931471805599453), xc);
    } else {  // Cody-Waite: k ln2_hi is exact, so unfused rounding stays at 1 ulp of r
      r = xsimd::fnma(k, B(1.42860682030941723212e-6), xsimd::fnma(k, B(6.93145751953125e-1), xc));
    }
    // Estrin's scheme: a dependency chain of 5 FMAs instead of Horner's 12.
    const B r2 = r * r, r4 = r2 * r2, r8 = r4 * r4;
    auto pair = [&](double c0, double c1) { return xsimd::fma(r, B(c1), B(c0)); };  // c0 + c1 r
    const B p01 = pair(1.0, 1.0), p23 = pair(1.0 / 2, 1.0 / 6), p45 = pair(1.0 / 24, 1.0 / 120),
            p67 = pair(1.0 / 720, 1.0 / 5040), p89 = pair(1.0 / 40320, 1.0 / 362880),
            p1011 = pair(1.0 / 3628800, 1.0 / 39916800);
    const B p03 = xsimd::fma(r2, p23, p01), p47 = xsimd::fma(r2, p67, p45),
            p811 = xsimd::fma(r2, p1011, p89);
    const B p812 = xsimd::fma(r4, B(1.0 / 479001600), p811);
    const B p = xsimd::fma(r8, p812, xsimd::fma(r4, p47, p03));
    const I scaled = xsimd::bitwise_cast<I>(p) + (xsimd::bitwise_cast<I>(kd) << 52);
    return xsimd::bitwise_cast<B>(scaled);
  }
  static B sqrt(B x) { return xsimd::sqrt(x); }
  static B pow(B x, double y) { return xsimd::pow(x, B(y)); }
  // Whether roots go through rsqrt below rather than sqrt and division: only where the hardware
  // gives an estimate to refine (measured: a bit-trick seed with Newton steps loses to vsqrtpd on
  // AVX2 and SSE4.2).
  static constexpr bool kEstimatedRsqrt = std::is_same_v<A, xsimd::avx512f>;
  // 1/sqrt(x) for x > 0 without a square root or division (AVX-512F only): the hardware estimate
  // (error < 2^-14) refined by one step of the series y (1 - e)^-1/2 with e = 1 - x y^2, to e^3
  // (truncation ~6e-17).
  static B rsqrt(B x) {
    const B y = B(_mm512_rsqrt14_pd(x));
    const B e = xsimd::fnma(x, y * y, B(1.0));
    const B series = xsimd::fma(e, xsimd::fma(e, B(5.0 / 16), B(3.0 / 8)), B(0.5));
    return xsimd::fma(y * e, series, y);
  }
  // x^-1/8 for x > 0 (AVX-512F only): three chained 14-bit estimates (error < 2^-13), then one
  // step of the series y (1 - e)^-1/8 with e = 1 - x y^8, to e^4 (truncation ~1e-17).
  static B inverse_eighth_root(B x) {
    B y = B(_mm512_rsqrt14_pd(_mm512_rsqrt14_pd(_mm512_rsqrt14_pd(x))));
    const B y2 = y * y, y4 = y2 * y2;
    const B e = xsimd::fnma(x, y4 * y4, B(1.0));
    const B series =
        e * xsimd::fma(e, xsimd::fma(e, xsimd::fma(e, B(663.0 / 32768), B(51.0 / 1024)), B(9.0 / 128)), B(1.0 / 8));
    return xsimd::fma(y, series, y);
  }
  static double sum(B x) { return xsimd::hadd(x); }
};

}  // namespace
}  // namespace stampede::kernels
