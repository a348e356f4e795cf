// Bluestein resampling (engine/metacal/chirp_resampler): rows evaluated at stretched positions agree
// with the dense trigonometric sum, at integer positions they return the row itself, and a repeated
// (a, b) is served from the cache with the same values; complex columns likewise against their
// dense sum (the Nyquist term split between +-M/2) and, at integer positions, FFTW's backward c2c.
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

// g(p) = sum over k = -M/2 .. M/2 of W_k F_k e^{2 pi i k p / M}, W = M (M/2 at +-M/2).
std::complex<double> dense_column(const std::vector<std::complex<double>>& f, double p) {
  const int m = static_cast<int>(f.size());
  std::complex<double> g = 0;
  for (int k = -m / 2; k <= m / 2; ++k)
    g += (std::abs(k) == m / 2 ? 0.5 : 1.0) * m * f[(k + m) % m] * std::polar(1.0, 2 * std::numbers::pi * k * p / m);
  return g;
}

TEST(ChirpResampler, ColumnsAgreeWithTheDenseSum) {
  constexpr int kPeriod = 96, kOut = 70, kColumns = 3, kStride = 5;
  RandomStream rng({11});
  std::vector<std::complex<double>> columns(kPeriod * kStride);
  for (auto& v : columns) v = {rng.normal(), rng.normal()};
  ChirpResampler r(kPeriod, kOut, FftPlanning::kEstimate);
  for (const auto& [a, b] : {std::pair{13.0, 1.0}, {12.7, 0.99}, {13.3, 1.0101}}) {
    std::vector<std::complex<double>> out(kOut * kColumns);
    r.resample_columns(columns.data(), kColumns, kStride, a, b, out.data(), kColumns);
    for (int c = 0; c < kColumns; ++c) {
      std::vector<std::complex<double>> f(kPeriod);
      for (int k = 0; k < kPeriod; ++k) f[k] = columns[k * kStride + c];
      for (int j = 0; j < kOut; ++j) {
        const std::complex<double> want = dense_column(f, a + b * j);
        EXPECT_NEAR(out[j * kColumns + c].real(), want.real(), 1e-9) << "a " << a << " b " << b << " j " << j;
        EXPECT_NEAR(out[j * kColumns + c].imag(), want.imag(), 1e-9) << "a " << a << " b " << b << " j " << j;
        if (b == 1.0 && a == 13.0) {  // integer positions: M times the backward c2c (unnormalised)
          std::complex<double> c2c = 0;
          for (int k = 0; k < kPeriod; ++k) c2c += f[k] * std::polar(1.0, 2 * std::numbers::pi * k * (13 + j) / kPeriod);
          EXPECT_NEAR(std::abs(out[j * kColumns + c] - static_cast<double>(kPeriod) * c2c), 0.0, 1e-9);
        }
      }
    }
  }
}

}  // namespace
}  // namespace stampede
