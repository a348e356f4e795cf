// Bluestein resampling of periodic rows; see chirp_resampler.hpp.
#include "engine/metacal/chirp_resampler.hpp"

#include <fftw3.h>

#include <algorithm>
#include <cmath>
#include <mutex>
#include <numbers>
#include <stdexcept>
#include <string>

#include "kernels/math/complex_product.hpp"
#include "kernels/math/fft_size.hpp"

namespace stampede {
namespace {

constexpr int kCacheSlots = 8;  // a cell's two stretched images use four (a, b), data and fixnoise alike

}  // namespace

ChirpResampler::ChirpResampler(int period, int outputs, FftPlanning planning)
    : m_(period), h_(period / 2 + 1), s_(outputs), l_(kernels::fft_friendly_size(period / 2 + outputs)) {
  work_ = AlignedBuffer(static_cast<std::size_t>(l_) * sizeof(fftw_complex));
  auto* w = static_cast<fftw_complex*>(work_.data());
  const unsigned flags = planning == FftPlanning::kMeasure ? FFTW_MEASURE : FFTW_ESTIMATE;
  {
    std::lock_guard<std::mutex> lock(fftw_planner_mutex());
    forward_ = fftw_plan_dft_1d(l_, w, w, FFTW_FORWARD, flags);
    backward_ = fftw_plan_dft_1d(l_, w, w, FFTW_BACKWARD, flags);
  }
  if (!forward_ || !backward_) throw std::runtime_error("ChirpResampler: FFTW could not plan " + std::to_string(l_) + " points");
  cache_.resize(kCacheSlots);
}

ChirpResampler::~ChirpResampler() {
  std::lock_guard<std::mutex> lock(fftw_planner_mutex());
  for (void* p : {forward_, backward_})
    if (p) fftw_destroy_plan(static_cast<fftw_plan>(p));
}

const ChirpResampler::Chirps& ChirpResampler::chirps_for(double a, double b) {
  ++clock_;
  for (Chirps& c : cache_)
    if (c.used > 0 && c.a == a && c.b == b) {
      c.used = clock_;
      return c;
    }
  Chirps& c = *std::min_element(cache_.begin(), cache_.end(), [](const Chirps& x, const Chirps& y) { return x.used < y.used; });
  c.a = a, c.b = b, c.used = clock_;
  const double k = 2 * std::numbers::pi / m_;
  c.pre.resize(static_cast<std::size_t>(h_));
  for (int q = 0; q < h_; ++q) {
    const double wq = (q == 0 || q == m_ / 2 ? 1.0 : 2.0) / m_;
    c.pre[q] = std::polar(wq, k * (q * a + 0.5 * b * q * q));
  }
  // v_k for k in [-(h - 1), S - 1], laid out circularly, and its transform.
  auto* w = reinterpret_cast<std::complex<double>*>(work_.data());
  std::fill(w, w + l_, std::complex<double>(0, 0));
  for (int j = -(h_ - 1); j < s_; ++j) w[(j + l_) % l_] = std::polar(1.0, -k * 0.5 * b * j * j);
  fftw_execute(static_cast<fftw_plan>(forward_));
  c.kernel.assign(w, w + l_);
  c.post.resize(static_cast<std::size_t>(s_));
  for (int j = 0; j < s_; ++j) c.post[j] = std::polar(1.0 / l_, k * 0.5 * b * j * j);
  return c;
}

void ChirpResampler::resample(const std::complex<double>* rows, int n, double a, double b, double* out, int out_stride) {
  const Chirps& c = chirps_for(a, b);
  auto* w = reinterpret_cast<std::complex<double>*>(work_.data());
  for (int r = 0; r < n; ++r) {
    const std::complex<double>* f = rows + static_cast<std::size_t>(r) * h_;
    kernels::complex_product(f, c.pre.data(), w, static_cast<std::size_t>(h_));
    std::fill(w + h_, w + l_, std::complex<double>(0, 0));
    fftw_execute(static_cast<fftw_plan>(forward_));
    kernels::complex_scale(w, c.kernel.data(), static_cast<std::size_t>(l_));
    fftw_execute(static_cast<fftw_plan>(backward_));
    double* o = out + static_cast<std::size_t>(r) * out_stride;
    const double* wd = reinterpret_cast<const double*>(w);
    const double* pd = reinterpret_cast<const double*>(c.post.data());
    for (int j = 0; j < s_; ++j) o[j] = wd[2 * j] * pd[2 * j] - wd[2 * j + 1] * pd[2 * j + 1];
  }
}

}  // namespace stampede
