// The noise of metacal's images; see metacal_noise.hpp.
#include "engine/metacal/metacal_noise.hpp"

#include <fftw3.h>

#include <algorithm>
#include <cmath>
#include <complex>
#include <mutex>
#include <stdexcept>
#include <string>

namespace stampede {

void metacal_noise_power(const MetacalFilters& filters, double input_variance, bool fixnoise, std::vector<double>* power) {
  const int m = filters.period(), h = m / 2 + 1;
  const std::complex<double>* f = filters.filter(MetacalType::kNoshear);  // 1 / M^2 included
  // |f|^2 at half-spectrum row r (0 .. M-1) and column c (0 .. M/2).
  auto norm_at = [&](int r, int c) { return std::norm(f[static_cast<std::size_t>(r) * h + c]); };
  // Var = sigma^2 / M^2 sum_k |a~|^2 |f M^2|^2 = sigma^2 M^2 sum_k |a~|^2 |f|^2.
  const double scale = input_variance * static_cast<double>(m) * m;
  power->resize(static_cast<std::size_t>(m) * h);
  for (int r = 0; r < m; ++r) {
    const int rs = r <= m / 2 ? r : r - m;  // signed; the Nyquist row as +M/2
    for (int c = 0; c < h; ++c) {
      double p = norm_at(r, c);
      if (fixnoise) {
        // k = (c, rs) turned by 90 degrees is (-rs, c); |f| is even (f Hermitian), so for rs > 0
        // read it at (rs, -c). Both Nyquist edges hold the mean of their two signs.
        p += rs <= 0 ? norm_at(c % m, -rs) : norm_at((m - c) % m, rs);
      }
      (*power)[static_cast<std::size_t>(r) * h + c] = (c == 0 || c == m / 2 ? 1.0 : 2.0) * scale * p;
    }
  }
}

NoiseSpectrum::NoiseSpectrum(int stamp_size, int period) : s_(stamp_size), m_(period) {
  if (stamp_size < 1 || period < stamp_size || period % 2 != 0)
    throw std::invalid_argument("NoiseSpectrum: period must be even and >= the stamp size");
  const int h = m_ / 2 + 1;
  padded_ = AlignedBuffer(static_cast<std::size_t>(m_) * m_ * sizeof(double));
  spectrum_ = AlignedBuffer(static_cast<std::size_t>(m_) * h * sizeof(fftw_complex));
  auto* pad = static_cast<double*>(padded_.data());
  {
    std::lock_guard<std::mutex> lock(fftw_planner_mutex());
    plan_ = fftw_plan_dft_r2c_2d(m_, m_, pad, static_cast<fftw_complex*>(spectrum_.data()), FFTW_ESTIMATE);
  }
  if (!plan_) throw std::runtime_error("NoiseSpectrum: FFTW could not plan a " + std::to_string(m_) + "-point grid");
  // The map goes in the top-left corner (the variance does not depend on where: the noise is
  // stationary); the rest stays zero (an out-of-place r2c keeps its input).
  std::fill(pad, pad + static_cast<std::size_t>(m_) * m_, 0.0);
}

NoiseSpectrum::~NoiseSpectrum() {
  std::lock_guard<std::mutex> lock(fftw_planner_mutex());
  if (plan_) fftw_destroy_plan(static_cast<fftw_plan>(plan_));
}

double NoiseSpectrum::variance(std::span<const double> a, std::span<const double> power) {
  const int h = m_ / 2 + 1;
  if (a.size() != static_cast<std::size_t>(s_) * s_ || power.size() != static_cast<std::size_t>(m_) * h)
    throw std::invalid_argument("NoiseSpectrum::variance: sizes do not match the grid");
  auto* pad = static_cast<double*>(padded_.data());
  for (int y = 0; y < s_; ++y) std::copy_n(a.data() + static_cast<std::size_t>(y) * s_, s_, pad + static_cast<std::size_t>(y) * m_);
  fftw_execute(static_cast<fftw_plan>(plan_));
  const auto* spec = static_cast<const std::complex<double>*>(spectrum_.data());
  double sum = 0;
  for (std::size_t i = 0; i < power.size(); ++i) sum += std::norm(spec[i]) * power[i];
  return sum;
}

EquivalentWeights equivalent_weights(double radius, double gamma_fwhm) {
  return {std::hypot(2.0 * radius, gamma_fwhm), std::hypot(2.43 * radius, 1.5 * gamma_fwhm)};
}

void correct_fit_for_correlated_noise(std::span<kernels::MomentsStamp> stamps, const EquivalentWeights& weights,
                                      std::vector<double>& scratch, FitResult* r) {
  std::vector<kernels::PixelCovariance*> kept(stamps.size());
  for (std::size_t k = 0; k < stamps.size(); ++k) kept[k] = stamps[k].covariance;
  // The moments under `fwhm` with the images' noise and as if it were white.
  auto both = [&](double fwhm, kernels::WeightedMoments* correlated, kernels::WeightedMoments* white) {
    for (std::size_t k = 0; k < stamps.size(); ++k) stamps[k].covariance = kept[k];
    *correlated = kernels::weighted_moments(stamps, fwhm, scratch);
    for (kernels::MomentsStamp& s : stamps) s.covariance = nullptr;
    *white = kernels::weighted_moments(stamps, fwhm, scratch);
    for (std::size_t k = 0; k < stamps.size(); ++k) stamps[k].covariance = kept[k];
    return correlated->valid && white->valid;
  };
  auto ratio = [](double a, double b) { return a > 0 && b > 0 && std::isfinite(a) && std::isfinite(b) ? a / b : NAN; };
  kernels::WeightedMoments correlated, white;
  double ks = NAN, k1 = NAN, k2 = NAN;
  // snr = flux / sd(flux): it falls by the ratio the flux's sd grows by.
  if (both(weights.snr_fwhm, &correlated, &white)) ks = ratio(correlated.snr, white.snr);
  if (both(weights.shape_fwhm, &correlated, &white)) {
    k1 = ratio(correlated.e1_err, white.e1_err);
    k2 = ratio(correlated.e2_err, white.e2_err);
  }
  if (std::isnan(k1) || std::isnan(k2) || std::isnan(ks)) r->flags |= kFlagNoErrors;
  r->e1_err *= k1;
  r->e2_err *= k2;
  r->errors[index(Param::kE1)] = r->e1_err;
  r->errors[index(Param::kE2)] = r->e2_err;
  r->snr *= ks;
}

}  // namespace stampede
