// The spectrum fold written once over a complex lane type: ComplexLanes<double> (the scalar
// reference, one complex value) or ComplexLanes<xsimd::batch<double, Arch>> (width / 2 complex
// values, interleaved as in memory). Included only by spectrum_fold_<isa>.cpp.
//
// Each output value's U^2 terms are summed in registers, unreduced: for a = (ar, ai), b = (br, bi)
// two running sums take the lane-wise products a * b = (ar br, ai bi) and a * swap(b) =
// (ar bi, ai br), and the real and imaginary parts (ar br - ai bi, ar bi + ai br) are formed once
// at the end. A vector step then needs no shuffle of a and one of b. The conjugates of the
// mirrored columns are (ar, -ai): the same sums with ai negated.
#pragma once

#include <algorithm>
#include <cstddef>
#include <cstdint>

#include "kernels/lanes.hpp"
#include "kernels/spectrum_fold.hpp"

namespace stampede::kernels {
namespace {

template <class T>
struct ComplexLanes {  // the scalar reference: one complex value
  struct V {
    double re, im;
  };
  static constexpr int complex_per_vector = 1;
  static V load(const double* p) { return {p[0], p[1]}; }
  static void store(double* p, V v) {
    p[0] = v.re;
    p[1] = v.im;
  }
  static V swap(V v) { return {v.im, v.re}; }
  static V conj(V v) { return {v.re, -v.im}; }
  static V reverse(V v) { return v; }
  static V zero() { return {0.0, 0.0}; }
  static V multiply_add(V a, V b, V c) { return {a.re * b.re + c.re, a.im * b.im + c.im}; }
  // The product's (re, im) from the unreduced sums s1 = (ar br, ai bi), s2 = (ar bi, ai br).
  static V combine(V s1, V s2) { return {s1.re - s1.im, s2.re + s2.im}; }
};

template <class A>
struct ComplexLanes<xsimd::batch<double, A>> {
  using V = xsimd::batch<double, A>;
  using Index = xsimd::batch<std::uint64_t, A>;
  static constexpr int complex_per_vector = static_cast<int>(V::size) / 2;
  struct SwapPairs {
    static constexpr std::uint64_t get(std::size_t i, std::size_t) { return i ^ 1u; }
  };
  struct ReversePairs {
    static constexpr std::uint64_t get(std::size_t i, std::size_t n) { return n - 2 - (i & ~std::size_t{1}) + (i & 1u); }
  };
  struct ConjugateSigns {
    static constexpr double get(std::size_t i, std::size_t) { return (i & 1u) ? -1.0 : 1.0; }
  };
  static V load(const double* p) { return V::load_unaligned(p); }
  static void store(double* p, V v) { v.store_unaligned(p); }
  static V swap(V v) { return xsimd::swizzle(v, xsimd::make_batch_constant<Index, SwapPairs>()); }
  static V conj(V v) { return v * xsimd::make_batch_constant<V, ConjugateSigns>(); }
  static V reverse(V v) {
    if constexpr (complex_per_vector == 1) return v;
    else return xsimd::swizzle(v, xsimd::make_batch_constant<Index, ReversePairs>());
  }
  static V zero() { return V(0.0); }
  static V multiply_add(V a, V b, V c) { return xsimd::fma(a, b, c); }
  struct EvenLanes {
    static constexpr bool get(std::size_t i, std::size_t) { return (i & 1u) == 0; }
  };
  static V combine(V s1, V s2) {
    return xsimd::select(xsimd::make_batch_bool_constant<V, EvenLanes>(), s1 - swap(s1), s2 + swap(s2));
  }
};

// The complex values X[ky][kx] for kx = k0 + j .. k0 + j + count - 1, as one lane vector: stored
// columns (kx < hn) directly, the others as conjugates of X[-ky][n - kx], lane by lane where a
// vector straddles the two.
template <class L>
inline typename L::V spectrum_columns(const double* row, const double* mirror, int n, int hn, int k0, int j) {
  constexpr int N = L::complex_per_vector;
  if (k0 + j + N <= hn) return L::load(row + 2 * (k0 + j));
  if (k0 + j >= hn) return L::conj(L::reverse(L::load(mirror + 2 * (n - k0 - j - (N - 1)))));
  alignas(64) double lanes[2 * N];
  for (int c = 0; c < N; ++c) {
    const int kx = k0 + j + c;
    lanes[2 * c] = kx < hn ? row[2 * kx] : mirror[2 * (n - kx)];
    lanes[2 * c + 1] = kx < hn ? row[2 * kx + 1] : -mirror[2 * (n - kx) + 1];
  }
  return L::load(lanes);
}

// K vectors of output row q side by side (independent accumulator chains), vector v < K - 1 at
// column j + v N and the last at column `last` (j + (K - 1) N, or M/2 + 1 - N where it overlaps
// its neighbour to end the row): all U^2 terms summed in registers (ky = q + M t ascending, then
// rx), reduced, stored.
template <class L, int K>
void fold_columns(int n, int u, int q, int j, int last, const double* spectrum, const double* kernel, double* out) {
  using V = typename L::V;
  constexpr int N = L::complex_per_vector;
  const int m = n / u, hn = n / 2 + 1, hm = m / 2 + 1;
  auto column = [&](int v) { return v == K - 1 ? last : j + v * N; };
  V s1[K], s2[K], a[K];
#pragma GCC unroll 8
  for (int v = 0; v < K; ++v) s1[v] = s2[v] = L::zero();
  for (int ky = q; ky < n; ky += m) {
    const double* row = spectrum + 2 * static_cast<std::size_t>(ky) * hn;
    const double* mirror = spectrum + 2 * static_cast<std::size_t>((n - ky) % n) * hn;
    for (int rx = 0; rx < u; ++rx) {
      const int k0 = m * rx;
      if (k0 + last + N <= hn) {  // all stored columns
#pragma GCC unroll 8
        for (int v = 0; v < K; ++v) a[v] = L::load(row + 2 * (k0 + column(v)));
      } else if (k0 + j >= hn) {  // all mirrored
#pragma GCC unroll 8
        for (int v = 0; v < K; ++v) a[v] = L::conj(L::reverse(L::load(mirror + 2 * (n - k0 - column(v) - (N - 1)))));
      } else {
#pragma GCC unroll 8
        for (int v = 0; v < K; ++v) a[v] = spectrum_columns<L>(row, mirror, n, hn, k0, column(v));
      }
      const double* b = kernel + 2 * (static_cast<std::size_t>(ky) * u + rx) * hm;
#pragma GCC unroll 8
      for (int v = 0; v < K; ++v) {
        const V bv = L::load(b + 2 * column(v));
        s1[v] = L::multiply_add(a[v], bv, s1[v]);
        s2[v] = L::multiply_add(a[v], L::swap(bv), s2[v]);
      }
    }
  }
  double* out_row = out + 2 * static_cast<std::size_t>(q) * hm;
#pragma GCC unroll 8
  for (int v = 0; v < K; ++v) L::store(out_row + 2 * column(v), L::combine(s1[v], s2[v]));
}

// Output row q: its whole vectors, plus one ending at the row's end where M/2 + 1 is not a multiple
// of the width (the columns it repeats come out bitwise the same: each lane's terms and operations
// are its column's alone), in as few passes as the registers allow, split evenly: every pass
// re-reads the U^2 spectrum segments of the row, so a lone leftover vector would cost a whole pass.
template <class L>
void fold_row(int n, int u, int q, const double* spectrum, const double* kernel, double* out) {
  constexpr int N = L::complex_per_vector;
  constexpr int kMaxK = N >= 4 ? 8 : 4;  // 2 K accumulators in 32 or 16 registers
  const int hm = (n / u) / 2 + 1;
  const int whole = hm / N, vectors = whole + (hm % N ? 1 : 0);
  const int passes = (vectors + kMaxK - 1) / kMaxK;
  int first = 0;
  for (int p = 0; p < passes; ++p) {
    const int k = vectors / passes + (p < vectors % passes ? 1 : 0);
    const int j = first * N, end = first + k;
    const int last = end - 1 < whole ? (end - 1) * N : hm - N;
    switch (k) {
      case 1: fold_columns<L, 1>(n, u, q, j, last, spectrum, kernel, out); break;
      case 2: fold_columns<L, 2>(n, u, q, j, last, spectrum, kernel, out); break;
      case 3: fold_columns<L, 3>(n, u, q, j, last, spectrum, kernel, out); break;
      case 4: fold_columns<L, 4>(n, u, q, j, last, spectrum, kernel, out); break;
      case 5: fold_columns<L, 5>(n, u, q, j, last, spectrum, kernel, out); break;
      case 6: fold_columns<L, 6>(n, u, q, j, last, spectrum, kernel, out); break;
      case 7: fold_columns<L, 7>(n, u, q, j, last, spectrum, kernel, out); break;
      default: fold_columns<L, 8>(n, u, q, j, last, spectrum, kernel, out); break;
    }
    first = end;
  }
}

template <class T>
void fold_lanes(int n, int u, const double* spectrum, const double* kernel, double* out) {
  using C = ComplexLanes<T>;
  const int hm = (n / u) / 2 + 1;
  for (int q = 0; q < n / u; ++q) {
    if (hm < C::complex_per_vector) fold_row<ComplexLanes<double>>(n, u, q, spectrum, kernel, out);
    else fold_row<C>(n, u, q, spectrum, kernel, out);
  }
}

template <class T>
SpectrumFoldKernels make_spectrum_fold_kernels(const char* name) {
  SpectrumFoldKernels k;
  k.name = name;
  k.lanes = Lanes<T>::size;
  k.fold = fold_lanes<T>;
  return k;
}

}  // namespace
}  // namespace stampede::kernels
