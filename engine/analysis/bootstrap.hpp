// Bootstrap standard errors over units (ring pairs, shear-pair members, lone objects): each
// resample draws as many units as there are, with replacement, as per-unit counts, and the whole
// estimate is repeated with them. splitmix64 from a seed is identical on every platform, so the
// errors are reproducible.
#pragma once

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <vector>

#include "engine/common/random_stream.hpp"

namespace stampede {

// The standard deviations of the K statistics estimate(counts) returns (a std::array<double, K>)
// over `resamples` draws of count->size() units (*count is the scratch the counts are drawn into);
// a draw with a non-finite statistic is skipped. NaN for fewer than two units (one resamples to
// itself every time: that is no error, not a zero one) and when fewer than two draws were usable.
template <std::size_t K, class Estimate>
std::array<double, K> bootstrap_errors(std::vector<int>* count, int resamples, std::uint64_t seed, Estimate&& estimate) {
  std::array<double, K> err;
  err.fill(NAN);
  const std::size_t n = count->size();
  if (n < 2) return err;
  std::array<double, K> sum{}, sum2{};
  std::uint64_t state = seed;
  int done = 0;
  for (int b = 0; b < resamples; ++b) {
    std::fill(count->begin(), count->end(), 0);
    for (std::size_t k = 0; k < n; ++k) ++(*count)[splitmix64(state) % n];
    const std::array<double, K> q = estimate(*count);
    if (!std::all_of(q.begin(), q.end(), [](double x) { return std::isfinite(x); })) continue;
    for (std::size_t i = 0; i < K; ++i) sum[i] += q[i], sum2[i] += q[i] * q[i];
    ++done;
  }
  if (done > 1)
    for (std::size_t i = 0; i < K; ++i) {
      const double mean = sum[i] / done;
      err[i] = std::sqrt(std::max(0.0, sum2[i] / done - mean * mean));
    }
  return err;
}

}  // namespace stampede
