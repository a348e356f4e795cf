// The least-squares accumulations written once over a lane type T (Lanes<double> the scalar
// reference, Lanes<xsimd::batch<double, Arch>> a vector). Included only by the per-ISA translation
// units (least_squares_<isa>.cpp).
//
// Masked pixels (w == 0) may hold anything, NaN and Inf included, in data, model and columns: every
// value read there is replaced by 0 before it is multiplied, so they add exactly +0 to each sum.
// Sums are lane partial sums over the pixels in order, then the lanes in order, then the tail: a
// fixed order for each instruction set.
#pragma once

#include <array>
#include <cstddef>
#include <span>
#include <type_traits>
#include <utility>

#include "kernels/lanes.hpp"
#include "kernels/least_squares.hpp"

namespace stampede::kernels {
namespace {

template <class T>
double weighted_chi2_lanes(std::span<const double> data, std::span<const double> model, std::span<const double> weight) {
  using L = Lanes<T>;
  constexpr std::size_t W = L::size;
  auto term = [](auto d, auto m, auto w) {
    using U = decltype(w);
    const auto used = w != U(0.0);
    const U r = Lanes<U>::all(used) ? d - m : Lanes<U>::select(used, d - m, U(0.0));
    return w * r * r;
  };
  const std::size_t n = data.size();
  T acc0(0.0), acc1(0.0);  // two chains: the add latency would otherwise bound the loop
  std::size_t i = 0;
  for (; i + 2 * W <= n; i += 2 * W) {
    acc0 += term(L::load(&data[i]), L::load(&model[i]), L::load(&weight[i]));
    acc1 += term(L::load(&data[i + W]), L::load(&model[i + W]), L::load(&weight[i + W]));
  }
  for (; i + W <= n; i += W) acc0 += term(L::load(&data[i]), L::load(&model[i]), L::load(&weight[i]));
  double chi2 = L::sum(acc0 + acc1);
  for (; i < n; ++i) chi2 += term(data[i], model[i], weight[i]);
  return chi2;
}

// Rows K0..K1-1 of alpha (columns 0..K) and beta[K] in one pass over the pixels, accumulators in
// registers; the masked columns 0..K1-1 are loaded and cleaned once per pixel for the whole block.
template <class T, int K0, int K1>
void normal_equations_block(std::span<const double> data, std::span<const double> model,
                            std::span<const double> weight, const double* const* columns, int ncol, double* alpha,
                            double* beta) {
  using L = Lanes<T>;
  constexpr std::size_t W = L::size;
  constexpr int R = K1 - K0;
  const double* col[K1];  // local: stores to the accumulators cannot alias it
  for (int l = 0; l < K1; ++l) col[l] = columns[l];
  const double* const d_ptr = data.data();
  const double* const m_ptr = model.data();
  const double* const w_ptr = weight.data();
  auto add_pixels = [&](auto (&a)[R][K1], auto (&b)[R], std::size_t i) {  // the W pixels from i (one in the tail)
    using U = std::remove_cvref_t<decltype(b[0])>;
    using M = Lanes<U>;
    const U zero(0.0), w = M::load(w_ptr + i);
    const auto used = w != zero;
    auto accumulate = [&](U r, auto column) {
      U c[K1];
#pragma GCC unroll 16
      for (int l = 0; l < K1; ++l) c[l] = column(l);
#pragma GCC unroll 16
      for (int k = 0; k < R; ++k) {
        const U wc = w * c[K0 + k];
        b[k] += wc * r;
#pragma GCC unroll 16
        for (int l = 0; l <= K0 + k; ++l) a[k][l] += wc * c[l];
      }
    };
    const U r = M::load(d_ptr + i) - M::load(m_ptr + i);
    if (M::all(used)) {  // the common case, no masked pixel: nothing to clean
      accumulate(r, [&](int l) { return M::load(col[l] + i); });
    } else if (M::any(used)) {
      accumulate(M::select(used, r, zero), [&](int l) { return M::select(used, M::load(col[l] + i), zero); });
    }  // all masked: they would add exactly +0
  };
  T va[R][K1], vb[R];
  for (int k = 0; k < R; ++k) {
    vb[k] = T(0.0);
    for (int l = 0; l <= K0 + k; ++l) va[k][l] = T(0.0);
  }
  const std::size_t n = data.size();
  std::size_t i = 0;
  for (; i + W <= n; i += W) add_pixels(va, vb, i);
  double ta[R][K1], tb[R];
  for (int k = 0; k < R; ++k) {
    tb[k] = L::sum(vb[k]);
    for (int l = 0; l <= K0 + k; ++l) ta[k][l] = L::sum(va[k][l]);
  }
  for (; i < n; ++i) add_pixels(ta, tb, i);
  for (int k = 0; k < R; ++k) {
    const int row = K0 + k;
    for (int l = 0; l <= row; ++l) alpha[row * ncol + l] = alpha[l * ncol + row] = ta[k][l];
    beta[row] = tb[k];
  }
}

// Rows [K0, min(K1, ncol)) as one block.
template <class T, int K0, int K1>
void normal_equations_rows(std::span<const double> data, std::span<const double> model,
                           std::span<const double> weight, const double* const* columns, int ncol, double* alpha,
                           double* beta) {
  if (K0 >= ncol) return;
  if constexpr (K1 - K0 > 1) {
    if (K1 > ncol) return normal_equations_rows<T, K0, K1 - 1>(data, model, weight, columns, ncol, alpha, beta);
  }
  normal_equations_block<T, K0, K1>(data, model, weight, columns, ncol, alpha, beta);
}

// Rows from `first` on, one block each.
template <class T, int first, int... K>
void normal_equations_single_rows(std::integer_sequence<int, K...>, std::span<const double> data,
                                  std::span<const double> model, std::span<const double> weight,
                                  const double* const* columns, int ncol, double* alpha, double* beta) {
  (normal_equations_rows<T, first + K, first + K + 1>(data, model, weight, columns, ncol, alpha, beta), ...);
}

template <class T>
double normal_equations_lanes(std::span<const double> data, std::span<const double> model,
                              std::span<const double> weight, const double* const* columns, int ncol, double* alpha,
                              double* beta) {
  // Blocks sized to the register file: 32 vector registers with AVX-512, 16 otherwise.
  constexpr int first_single = Lanes<T>::size >= 8 ? 6 : 3;
  if constexpr (Lanes<T>::size >= 8) {
    normal_equations_rows<T, 0, 4>(data, model, weight, columns, ncol, alpha, beta);
    normal_equations_rows<T, 4, 6>(data, model, weight, columns, ncol, alpha, beta);
  } else {
    normal_equations_rows<T, 0, 3>(data, model, weight, columns, ncol, alpha, beta);
  }
  normal_equations_single_rows<T, first_single>(std::make_integer_sequence<int, kMaxLeastSquaresColumns - first_single>(),
                                                data, model, weight, columns, ncol, alpha, beta);
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
