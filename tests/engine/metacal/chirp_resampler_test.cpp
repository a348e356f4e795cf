// Bluestein resampling (engine/metacal/chirp_resampler): rows evaluated at stretched positions agree
// with the dense trigonometric sum, at integer positions they return the row itself, and a repeated
// (a, b) is served from the cache with the same values.
#include "engine/metacal/chirp_resampler.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <complex>
#include <numbers>
#include <vector>

#include "engine/common/random_stream.hpp"

namespace stampede {
namespace {

// FFTW's r2c of a real row: F_q = sum_x row[x] e^{-2 pi i q x / M}, q = 0 .. M/2.
std::vector<std::complex<double>> half_spectrum(const std::vector<double>& row) {
  const int m = static_cast<int>(row.size());
  std::vector<std::complex<double>> f(m / 2 + 1);
  for (int q = 0; q <= m / 2; ++q)
    for (int x = 0; x < m; ++x) f[q] += row[x] * std::polar(1.0, -2 * std::numbers::pi * q * x / m);
  return f;
}

double dense(const std::vector<std::complex<double>>& f, int m, double p) {
  double v = 0;
  for (int q = 0; q <= m / 2; ++q)
    v += (q == 0 || q == m / 2 ? 1.0 : 2.0) / m * (f[q] * std::polar(1.0, 2 * std::numbers::pi * q * p / m)).real();
  return v;
}

TEST(ChirpResampler, AgreesWithTheDenseSum) {
  constexpr int kPeriod = 96, kOut = 70, kRows = 3;
  RandomStream rng({7});
  std::vector<std::complex<double>> spectra;
  std::vector<std::vector<double>> rows(kRows, std::vector<double>(kPeriod));
  for (auto& row : rows) {
    for (double& v : row) v = rng.normal();
    const auto f = half_spectrum(row);
    spectra.insert(spectra.end(), f.begin(), f.end());
  }
  ChirpResampler r(kPeriod, kOut, FftPlanning::kEstimate);
  for (const auto& [a, b] : {std::pair{13.0, 1.0}, {12.7, 0.99}, {13.3, 1.0101}}) {
    std::vector<double> out(kRows * kOut);
    r.resample(spectra.data(), kRows, a, b, out.data(), kOut);
    for (int k = 0; k < kRows; ++k)
      for (int j = 0; j < kOut; ++j) {
        const std::vector<std::complex<double>> f(spectra.begin() + k * (kPeriod / 2 + 1),
                                                  spectra.begin() + (k + 1) * (kPeriod / 2 + 1));
        EXPECT_NEAR(out[k * kOut + j], dense(f, kPeriod, a + b * j), 1e-12) << "a " << a << " b " << b << " j " << j;
        if (b == 1.0 && a == 13.0) {
          EXPECT_NEAR(out[k * kOut + j], rows[k][13 + j], 1e-12);
        }
      }
    std::vector<double> again(kRows * kOut);
    r.resample(spectra.data(), kRows, a, b, again.data(), kOut);
    EXPECT_EQ(out, again);
  }
}

}  // namespace
}  // namespace stampede
