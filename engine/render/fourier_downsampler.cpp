// Fourier-space downsampling; see fourier_downsampler.hpp.
#include "engine/render/fourier_downsampler.hpp"

#include <fftw3.h>

#include <algorithm>
#include <cmath>
#include <mutex>
#include <numbers>
#include <stdexcept>

namespace stampede {

FourierDownsampler::FourierDownsampler(const GridGeometry& g, kernels::Isa isa)
    : n_(g.size),
      u_(g.upsampling),
      m_(g.size / g.upsampling),
      stamp_size_(g.stamp_size),
      fold_(&kernels::spectrum_fold_kernels(isa)) {
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
  auto* y = static_cast<double*>(folded_.data());  // interleaved re, im
  fold_->fold(n_, u_, reinterpret_cast<const double*>(spectrum), reinterpret_cast<const double*>(folded_kernel), y);
  auto* pixels = static_cast<double*>(pixels_.data());
  fftw_execute_dft_c2r(static_cast<fftw_plan>(plan_), reinterpret_cast<fftw_complex*>(y), pixels);
  for (int py = 0; py < stamp_size_; ++py)
    std::copy_n(pixels + static_cast<std::size_t>(first_pixel_ + py) * m_ + first_pixel_, stamp_size_,
                stamp + static_cast<std::size_t>(py) * stamp_size_);
}

}  // namespace stampede
