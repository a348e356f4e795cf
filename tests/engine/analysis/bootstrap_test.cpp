// Tests for engine/analysis/bootstrap: the bootstrap error of a mean is the standard error
// sd / sqrt(n); one unit gives no error (NaN), not a zero one; draws with a non-finite statistic are
// skipped; the same seed gives the same errors.
#include "engine/analysis/bootstrap.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <numeric>
#include <vector>

namespace stampede {
namespace {

// The count-weighted mean of `values` (and, second, of their squares).
std::array<double, 2> weighted_means(const std::vector<double>& values, const std::vector<int>& count) {
  double s = 0, s2 = 0, n = 0;
  for (std::size_t i = 0; i < values.size(); ++i) s += count[i] * values[i], s2 += count[i] * values[i] * values[i], n += count[i];
  return {s / n, s2 / n};
}

TEST(Bootstrap, TheErrorOfAMeanIsItsStandardError) {
  std::vector<double> values(400);
  for (std::size_t i = 0; i < values.size(); ++i) values[i] = std::sin(0.7 * static_cast<double>(i)) + 0.01 * static_cast<double>(i % 7);
  const double mean = std::accumulate(values.begin(), values.end(), 0.0) / values.size();
  double var = 0;
  for (double v : values) var += (v - mean) * (v - mean);
  const double standard_error = std::sqrt(var / values.size()) / std::sqrt(static_cast<double>(values.size()));
  std::vector<int> count(values.size());
  const auto err = bootstrap_errors<2>(&count, 4000, 7, [&](const std::vector<int>& c) { return weighted_means(values, c); });
  // 4000 draws estimate a standard deviation to ~1.1 % (1 / sqrt(2 x 4000)): 5 % is 4.5 sigma.
  EXPECT_NEAR(err[0] / standard_error, 1.0, 0.05);
  EXPECT_GT(err[1], 0.0);
  const auto again = bootstrap_errors<2>(&count, 4000, 7, [&](const std::vector<int>& c) { return weighted_means(values, c); });
  EXPECT_EQ(err, again);
  const auto other = bootstrap_errors<2>(&count, 4000, 8, [&](const std::vector<int>& c) { return weighted_means(values, c); });
  EXPECT_NE(err[0], other[0]);
}

TEST(Bootstrap, OneUnitOrTooFewUsableDrawsGiveNoError) {
  std::vector<int> one(1);
  const auto single = bootstrap_errors<1>(&one, 100, 1, [](const std::vector<int>& c) { return std::array<double, 1>{1.0 * c[0]}; });
  EXPECT_TRUE(std::isnan(single[0]));
  std::vector<int> count(10);
  const auto none = bootstrap_errors<1>(&count, 100, 1, [](const std::vector<int>&) { return std::array<double, 1>{NAN}; });
  EXPECT_TRUE(std::isnan(none[0]));
  std::vector<int> empty;
  EXPECT_TRUE(std::isnan((bootstrap_errors<1>(&empty, 100, 1, [](const std::vector<int>&) { return std::array<double, 1>{1}; })[0])));
}

TEST(Bootstrap, DrawsWithANonFiniteStatisticAreSkipped) {
  std::vector<double> values = {1, 2, 3, 4, 5, 6, 7, 8};
  std::vector<int> count(values.size());
  int calls = 0;
  // Every other draw is unusable: the error must equal the one from the usable draws alone.
  const auto err = bootstrap_errors<1>(&count, 200, 3, [&](const std::vector<int>& c) {
    const bool usable = calls++ % 2 == 0;
    return std::array<double, 1>{usable ? weighted_means(values, c)[0] : INFINITY};
  });
  EXPECT_TRUE(std::isfinite(err[0]));
  EXPECT_GT(err[0], 0.0);
}

}  // namespace
}  // namespace stampede
