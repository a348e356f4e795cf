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
    const U r = Lanes<U>::select(w != U(0.0), d - m, U(0.0));
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

// Row K of alpha (columns 0..K) and beta[K] in one pass over the pixels, accumulators in registers.
template <class T, int K>
void normal_equations_row(std::span<const double> data, std::span<const double> model, std::span<const double> weight,
                          const double* const* columns, int ncol, double* alpha, double* beta) {
  using L = Lanes<T>;
  constexpr std::size_t W = L::size;
  struct Sums {
    T alpha[K + 1];
    T beta;
  };
  auto add_pixels = [&](auto& s, std::size_t i) {  // the W pixels from i (or one, in the tail)
    using U = std::remove_cvref_t<decltype(s.beta)>;
    using M = Lanes<U>;
    const U zero(0.0), w = M::load(&weight[i]);
    const auto used = w != zero;
    const U r = M::select(used, M::load(&data[i]) - M::load(&model[i]), zero);
    const U wc = w * M::select(used, M::load(&columns[K][i]), zero);
    s.beta += wc * r;
    for (int l = 0; l <= K; ++l) s.alpha[l] += wc * M::select(used, M::load(&columns[l][i]), zero);
  };
  Sums v;
  for (int l = 0; l <= K; ++l) v.alpha[l] = T(0.0);
  v.beta = T(0.0);
  const std::size_t n = data.size();
  std::size_t i = 0;
  for (; i + W <= n; i += W) add_pixels(v, i);
  struct TailSums {
    double alpha[K + 1];
    double beta;
  } t;
  for (int l = 0; l <= K; ++l) t.alpha[l] = L::sum(v.alpha[l]);
  t.beta = L::sum(v.beta);
  for (; i < n; ++i) add_pixels(t, i);
  for (int l = 0; l <= K; ++l) alpha[K * ncol + l] = alpha[l * ncol + K] = t.alpha[l];
  beta[K] = t.beta;
}

template <class T, int... K>
void normal_equations_rows(std::integer_sequence<int, K...>, std::span<const double> data,
                           std::span<const double> model, std::span<const double> weight, const double* const* columns,
                           int ncol, double* alpha, double* beta) {
  ((K < ncol ? normal_equations_row<T, K>(data, model, weight, columns, ncol, alpha, beta) : void()), ...);
}

template <class T>
double normal_equations_lanes(std::span<const double> data, std::span<const double> model,
                              std::span<const double> weight, const double* const* columns, int ncol, double* alpha,
                              double* beta) {
  normal_equations_rows<T>(std::make_integer_sequence<int, kMaxLeastSquaresColumns>(), data, model, weight, columns,
                           ncol, alpha, beta);
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
