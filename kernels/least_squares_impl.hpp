// The least-squares accumulations written once over a lane type T (Lanes<double> the scalar
// reference, Lanes<xsimd::batch<double, Arch>> a vector). Included only by the per-ISA translation
// units (least_squares_<isa>.cpp).
//
// Masked pixels (w == 0) may hold anything, NaN and Inf included, in data, model and columns. Each
// kernel first sums without looking at the mask: there a masked pixel with finite values adds
// products with a factor w = 0, that is ±0, which leave every sum bitwise unchanged (a sum that
// starts at +0 never becomes -0). Only a NaN or Inf under the mask can show, as a non-finite
// result; then the kernel sums again with every value read under the mask replaced by 0. Either way
// masked pixels add exactly nothing, and the two passes agree bit for bit where both are finite.
// Sums are lane partial sums over the pixels in order, then the lanes in order, then the tail: a
// fixed order for each instruction set.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <span>
#include <type_traits>
#include <utility>

#include "kernels/lanes.hpp"
#include "kernels/least_squares.hpp"

namespace stampede::kernels {
namespace {

// The residual r = d - m, and with kMasked the lanes under the mask (w == 0) replaced by 0.
template <bool kMasked, class U, class Used>
U masked_residual(U d, U m, Used used) {
  if constexpr (kMasked) return Lanes<U>::select(used, d - m, U(0.0));
  else return d - m;
}

template <class T, bool kMasked>
double weighted_chi2_pass(std::span<const double> data, std::span<const double> model, std::span<const double> weight) {
  using L = Lanes<T>;
  constexpr std::size_t W = L::size;
  auto term = [](auto d, auto m, auto w) {
    using U = decltype(w);
    const U r = masked_residual<kMasked>(d, m, w != U(0.0));
    return w * r * r;  // (w r) r: with w = 0 and a finite r exactly ±0
  };
  const std::size_t n = data.size();
  // Four chains: with fewer the add latency, not the loads, would bound the loop.
  T acc0(0.0), acc1(0.0), acc2(0.0), acc3(0.0);
  std::size_t i = 0;
  for (; i + 4 * W <= n; i += 4 * W) {
    acc0 += term(L::load(&data[i]), L::load(&model[i]), L::load(&weight[i]));
    acc1 += term(L::load(&data[i + W]), L::load(&model[i + W]), L::load(&weight[i + W]));
    acc2 += term(L::load(&data[i + 2 * W]), L::load(&model[i + 2 * W]), L::load(&weight[i + 2 * W]));
    acc3 += term(L::load(&data[i + 3 * W]), L::load(&model[i + 3 * W]), L::load(&weight[i + 3 * W]));
  }
  if (i + W <= n) acc0 += term(L::load(&data[i]), L::load(&model[i]), L::load(&weight[i])), i += W;
  if (i + W <= n) acc1 += term(L::load(&data[i]), L::load(&model[i]), L::load(&weight[i])), i += W;
  if (i + W <= n) acc2 += term(L::load(&data[i]), L::load(&model[i]), L::load(&weight[i])), i += W;
  double chi2 = L::sum((acc0 + acc1) + (acc2 + acc3));
  for (; i < n; ++i) chi2 += term(data[i], model[i], weight[i]);
  return chi2;
}

template <class T>
double weighted_chi2_lanes(std::span<const double> data, std::span<const double> model, std::span<const double> weight) {
  const double chi2 = weighted_chi2_pass<T, false>(data, model, weight);
  return std::isfinite(chi2) ? chi2 : weighted_chi2_pass<T, true>(data, model, weight);
}

// Pixels per chunk of the normal equations: every block of rows passes over a chunk's data, model,
// weight and columns while they are in the 48 KiB L1 (with 7 columns, 10 arrays of 4 KiB); over
// the whole stamp at once each block would stream them from L2, which bounds the wide sets.
inline constexpr std::size_t kNormalEquationsChunk = 512;

// The lane accumulators of the normal equations, kept across chunks.
template <class T>
struct NormalAccumulators {
  T alpha[kMaxLeastSquaresColumns][kMaxLeastSquaresColumns];  // lower triangle [k][l <= k]
  T beta[kMaxLeastSquaresColumns];
};

// Adds pixels [begin, end) (whole vectors) to rows K0..K1-1 of the accumulators (columns 0..row),
// held in registers over the range; the columns 0..K1-1 are loaded once per pixel for the block.
template <class T, bool kMasked, int K0, int K1>
void normal_equations_block(const double* d_ptr, const double* m_ptr, const double* w_ptr,
                            const double* const* columns, std::size_t begin, std::size_t end,
                            NormalAccumulators<T>& acc) {
  using L = Lanes<T>;
  constexpr std::size_t W = L::size;
  constexpr int R = K1 - K0;
  const double* col[K1];  // local: stores to the accumulators cannot alias it
  for (int l = 0; l < K1; ++l) col[l] = columns[l];
  T va[R][K1], vb[R];
  // Unrolled, the copies are register moves; as loops GCC makes them rep movs, slow per chunk.
#pragma GCC unroll 16
  for (int k = 0; k < R; ++k) {
    vb[k] = acc.beta[K0 + k];
#pragma GCC unroll 16
    for (int l = 0; l <= K0 + k; ++l) va[k][l] = acc.alpha[K0 + k][l];
  }
  const T zero(0.0);
  for (std::size_t i = begin; i < end; i += W) {
    const T w = L::load(w_ptr + i);
    const auto used = w != zero;
    if constexpr (kMasked) {
      if (!L::any(used)) continue;  // all masked: they would add exactly +0
    }
    const T r = masked_residual<kMasked>(L::load(d_ptr + i), L::load(m_ptr + i), used);
    T c[K1];
#pragma GCC unroll 16
    for (int l = 0; l < K1; ++l) {
      c[l] = L::load(col[l] + i);
      if constexpr (kMasked) c[l] = L::select(used, c[l], zero);
    }
#pragma GCC unroll 16
    for (int k = 0; k < R; ++k) {
      const T wc = w * c[K0 + k];
      vb[k] += wc * r;
#pragma GCC unroll 16
      for (int l = 0; l <= K0 + k; ++l) va[k][l] += wc * c[l];
    }
  }
#pragma GCC unroll 16
  for (int k = 0; k < R; ++k) {
    acc.beta[K0 + k] = vb[k];
#pragma GCC unroll 16
    for (int l = 0; l <= K0 + k; ++l) acc.alpha[K0 + k][l] = va[k][l];
  }
}

// Rows [K0, min(K1, ncol)) as one block.
template <class T, bool kMasked, int K0, int K1>
void normal_equations_rows(const double* d, const double* m, const double* w, const double* const* columns, int ncol,
                           std::size_t begin, std::size_t end, NormalAccumulators<T>& acc) {
  if (K0 >= ncol) return;
  if constexpr (K1 - K0 > 1) {
    if (K1 > ncol) return normal_equations_rows<T, kMasked, K0, K1 - 1>(d, m, w, columns, ncol, begin, end, acc);
  }
  normal_equations_block<T, kMasked, K0, K1>(d, m, w, columns, begin, end, acc);
}

// Rows from `first` on, one block each.
template <class T, bool kMasked, int first, int... K>
void normal_equations_single_rows(std::integer_sequence<int, K...>, const double* d, const double* m, const double* w,
                                  const double* const* columns, int ncol, std::size_t begin, std::size_t end,
                                  NormalAccumulators<T>& acc) {
  (normal_equations_rows<T, kMasked, first + K, first + K + 1>(d, m, w, columns, ncol, begin, end, acc), ...);
}

template <class T, bool kMasked>
void normal_equations_pass(std::span<const double> data, std::span<const double> model,
                           std::span<const double> weight, const double* const* columns, int ncol, double* alpha,
                           double* beta) {
  using L = Lanes<T>;
  constexpr std::size_t W = L::size;
  const double* const d = data.data();
  const double* const m = model.data();
  const double* const w = weight.data();
  NormalAccumulators<T> acc;
  for (int k = 0; k < ncol; ++k) {
    acc.beta[k] = T(0.0);
    for (int l = 0; l <= k; ++l) acc.alpha[k][l] = T(0.0);
  }
  const std::size_t n = data.size(), vector_end = n - n % W;
  for (std::size_t begin = 0; begin < vector_end; begin += kNormalEquationsChunk) {
    const std::size_t end = std::min(begin + kNormalEquationsChunk, vector_end);
    // Blocks sized to the register file: 32 vector registers with AVX-512, 16 otherwise.
    constexpr int first_single = W >= 8 ? 7 : 3;
    if constexpr (W >= 8) {
      normal_equations_rows<T, kMasked, 0, 5>(d, m, w, columns, ncol, begin, end, acc);
      normal_equations_rows<T, kMasked, 5, 7>(d, m, w, columns, ncol, begin, end, acc);
    } else {
      normal_equations_rows<T, kMasked, 0, 3>(d, m, w, columns, ncol, begin, end, acc);
    }
    normal_equations_single_rows<T, kMasked, first_single>(
        std::make_integer_sequence<int, kMaxLeastSquaresColumns - first_single>(), d, m, w, columns, ncol, begin, end,
        acc);
  }
  // Lanes reduced, then the tail pixels one by one, as the block kernel would with one lane.
  for (int k = 0; k < ncol; ++k) {
    beta[k] = L::sum(acc.beta[k]);
    for (int l = 0; l <= k; ++l) alpha[k * ncol + l] = L::sum(acc.alpha[k][l]);
  }
  for (std::size_t i = vector_end; i < n; ++i) {
    const bool used = w[i] != 0.0;
    if (kMasked && !used) continue;
    const double r = masked_residual<kMasked>(d[i], m[i], used);
    for (int k = 0; k < ncol; ++k) {
      const double wc = w[i] * columns[k][i];
      beta[k] += wc * r;
      for (int l = 0; l <= k; ++l) alpha[k * ncol + l] += wc * columns[l][i];
    }
  }
  for (int k = 0; k < ncol; ++k)
    for (int l = 0; l < k; ++l) alpha[l * ncol + k] = alpha[k * ncol + l];
}

template <class T>
double normal_equations_lanes(std::span<const double> data, std::span<const double> model,
                              std::span<const double> weight, const double* const* columns, int ncol, double* alpha,
                              double* beta) {
  normal_equations_pass<T, false>(data, model, weight, columns, ncol, alpha, beta);
  bool finite = true;
  for (int k = 0; k < ncol; ++k) {
    finite &= std::isfinite(beta[k]);
    for (int l = 0; l <= k; ++l) finite &= std::isfinite(alpha[k * ncol + l]);
  }
  if (!finite) normal_equations_pass<T, true>(data, model, weight, columns, ncol, alpha, beta);
  // chi2 by the same code as a trial step's, so the solver compares like with like, bit for bit.
  return weighted_chi2_lanes<T>(data, model, weight);
}

template <class T>
LeastSquaresKernels make_least_squares_kernels(const char* name) {
  LeastSquaresKernels k;
  k.name = name;
  k.lanes = Lanes<T>::size;
  k.weighted_chi2 = weighted_chi2_lanes<T>;
  k.normal_equations = normal_equations_lanes<T>;
  return k;
}

}  // namespace
}  // namespace stampede::kernels
