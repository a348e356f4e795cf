// Fourier-space downsampling; see fourier_downsampler.hpp.
#include "engine/fourier_downsampler.hpp"

#include <fftw3.h>

#include <algorithm>
#include <cmath>
#include <mutex>
#include <numbers>
#include <stdexcept>

namespace stampede {

FourierDownsampler::FourierDownsampler(const GridGeometry& g)
    : n_(g.size), u_(g.upsampling), m_(g.size / g.upsampling), stamp_size_(g.stamp_size) {
  if (n_ % u_ != 0) throw std::invalid_argument("FourierDownsampler: the grid is not a whole number of pixels");
  first_pixel_ = g.offset / u_;
  const int hm = m_ / 2 + 1;
  folded_ = AlignedBuffer(sizeof(fftw_complex) * static_cast<std::size_t>(m_) * hm);
  pixels_ = AlignedBuffer(sizeof(double) * static_cast<std::size_t>(m_) * m_);
  std::lock_guard<std::mutex> lock(fftw_planner_mutex());
  // ESTIMATE: an M x M transform is a small share of the work, and the plan is then deterministic.
  plan_ = fftw_plan_dft_c2r_2d(m_, m_, static_cast<fftw_complex*>(folded_.data()), static_cast<double*>(pixels_.data()),
                               FFTW_ESTIMATE | FFTW_DESTROY_INPUT);
  if (!plan_) throw std::runtime_error("FFTW could not plan the downsampling transform");
}

FourierDownsampler::~FourierDownsampler() {
  std::lock_guard<std::mutex> lock(fftw_planner_mutex());
  if (plan_) fftw_destroy_plan(static_cast<fftw_plan>(plan_));
}

std::vector<std::complex<double>> FourierDownsampler::fold_kernel(const GridGeometry& g,
                                                                 const std::complex<double>* kernel) {
  const int n = g.size, u = g.upsampling, m = n / u, hn = n / 2 + 1, hm = m / 2 + 1;
  if (n % u != 0) throw std::invalid_argument("FourierDownsampler: the grid is not a whole number of pixels");
  const int o = g.offset % u;
  std::vector<std::complex<double>> phase(static_cast<std::size_t>(n));  // P(k)
  for (int k = 0; k < n; ++k) {
    std::complex<double> box = 0;
    for (int t = 0; t < u; ++t) box += std::polar(1.0, 2 * std::numbers::pi * k * t / n);
    phase[static_cast<std::size_t>(k)] = std::polar(1.0, 2 * std::numbers::pi * k * o / n) * box / double(u);
  }
  std::vector<std::complex<double>> folded(static_cast<std::size_t>(n) * u * hm);
  for (int ky = 0; ky < n; ++ky)
    for (int rx = 0; rx < u; ++rx)
      for (int jx = 0; jx < hm; ++jx) {
        const int kx = jx + m * rx;
        const std::complex<double> k = kx < hn ? kernel[static_cast<std::size_t>(ky) * hn + kx]
                                               : std::conj(kernel[static_cast<std::size_t>((n - ky) % n) * hn + (n - kx)]);
        folded[(static_cast<std::size_t>(ky) * u + rx) * hm + jx] =
            k * phase[static_cast<std::size_t>(kx)] * phase[static_cast<std::size_t>(ky)];
      }
  return folded;
}

void FourierDownsampler::apply(const std::complex<double>* spectrum, const std::complex<double>* folded_kernel,
                               double* stamp) {
  // Complex products are spelled out in real arithmetic: std::complex's operator* must handle
  // inf/nan (C99 Annex G) and becomes a library call per product without -ffast-math.
  const int n = n_, m = m_, hn = n / 2 + 1, hm = m / 2 + 1;
  auto* y = static_cast<double*>(folded_.data());  // interleaved re, im
  std::fill(y, y + 2 * static_cast<std::size_t>(m) * hm, 0.0);
  const auto* spec = reinterpret_cast<const double*>(spectrum);
  const auto* keff = reinterpret_cast<const double*>(folded_kernel);
  // Only the columns kx = jx + M rx with jx <= M/2 feed the half spectrum of Y: U (M/2 + 1) of n.
  for (int ky = 0; ky < n; ++ky) {
    const std::size_t row = 2 * static_cast<std::size_t>(ky) * hn;
    const std::size_t mirror = 2 * static_cast<std::size_t>((n - ky) % n) * hn;
    double* out = y + 2 * static_cast<std::size_t>(ky % m) * hm;
    for (int rx = 0; rx < u_; ++rx) {
      const int k0 = m * rx;
      const double* b = keff + 2 * (static_cast<std::size_t>(ky) * u_ + rx) * hm;
      // Stored columns kx < hn directly, the rest as conjugates of the spectrum at -k.
      const int split = std::clamp(hn - k0, 0, hm);
      for (int jx = 0; jx < split; ++jx) {
        const double* a = spec + row + 2 * (k0 + jx);
        out[2 * jx] += a[0] * b[2 * jx] - a[1] * b[2 * jx + 1];
        out[2 * jx + 1] += a[0] * b[2 * jx + 1] + a[1] * b[2 * jx];
      }
      for (int jx = split; jx < hm; ++jx) {
        const double* a = spec + mirror + 2 * (n - k0 - jx);
        out[2 * jx] += a[0] * b[2 * jx] + a[1] * b[2 * jx + 1];
        out[2 * jx + 1] += a[0] * b[2 * jx + 1] - a[1] * b[2 * jx];
      }
    }
  }
  auto* pixels = static_cast<double*>(pixels_.data());
  fftw_execute_dft_c2r(static_cast<fftw_plan>(plan_), reinterpret_cast<fftw_complex*>(y), pixels);
  for (int py = 0; py < stamp_size_; ++py)
    std::copy_n(pixels + static_cast<std::size_t>(first_pixel_ + py) * m + first_pixel_, stamp_size_,
                stamp + static_cast<std::size_t>(py) * stamp_size_);
}

}  // namespace stampede
