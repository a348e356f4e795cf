// Bluestein resampling of periodic rows and columns; see chirp_resampler.hpp.
#include "engine/metacal/chirp_resampler.hpp"

#include <algorithm>
#include <cmath>
#include <mutex>
#include <numbers>
#include <stdexcept>
#include <string>

#include "engine/common/fftw_precision.hpp"
#include "kernels/math/complex_product.hpp"

namespace stampede {
namespace {

// A cell's two stretched images use four (a, b) of each form, data and fixnoise alike.
constexpr int kCacheSlots = 12;

// The convolution's length: the smallest 2^k, 5 x 2^k or 25 x 2^k (k >= 2) >= n. FFTW_ESTIMATE's
// plans of these run fastest at a cell's lengths, faster than shorter lengths with factors 3 or 7
// (540 points take 1.3x 640's; docs/metadetect.md, "Single-precision images").
int convolution_length(int n) {
  int best = 0;
  for (int base : {4, 20, 100}) {
    int l = base;
    while (l < n) l *= 2;
    if (best == 0 || l < best) best = l;
  }
  return best;
}

}  // namespace

template <class Real>
BasicChirpResampler<Real>::BasicChirpResampler(int period, int outputs, FftPlanning planning)
    : m_(period),
      h_(period / 2 + 1),
      s_(outputs),
      l_rows_(convolution_length(period / 2 + outputs)),
      l_columns_(convolution_length(period + outputs)) {
  using F = Fftw<Real>;
  rows_work_ = AlignedBuffer(static_cast<std::size_t>(l_rows_) * sizeof(Complex));
  columns_work_ = AlignedBuffer(static_cast<std::size_t>(l_columns_) * sizeof(Complex));
  auto* r = F::c(static_cast<Complex*>(rows_work_.data()));
  auto* c = F::c(static_cast<Complex*>(columns_work_.data()));
  const unsigned flags = planning == FftPlanning::kMeasure ? FFTW_MEASURE : FFTW_ESTIMATE;
  {
    std::lock_guard<std::mutex> lock(fftw_planner_mutex());
    rows_forward_ = F::dft_1d(l_rows_, r, r, FFTW_FORWARD, flags);
    rows_backward_ = F::dft_1d(l_rows_, r, r, FFTW_BACKWARD, flags);
    columns_forward_ = F::dft_1d(l_columns_, c, c, FFTW_FORWARD, flags);
    columns_backward_ = F::dft_1d(l_columns_, c, c, FFTW_BACKWARD, flags);
  }
  if (!rows_forward_ || !rows_backward_ || !columns_forward_ || !columns_backward_)
    throw std::runtime_error("ChirpResampler: FFTW could not plan " + std::to_string(l_rows_) + " and " +
                             std::to_string(l_columns_) + " points");
  cache_.resize(kCacheSlots);
}

template <class Real>
BasicChirpResampler<Real>::~BasicChirpResampler() {
  std::lock_guard<std::mutex> lock(fftw_planner_mutex());
  for (void* p : {rows_forward_, rows_backward_, columns_forward_, columns_backward_})
    if (p) Fftw<Real>::destroy(p);
}

template <class Real>
const typename BasicChirpResampler<Real>::Chirps& BasicChirpResampler<Real>::chirps_for(bool columns, double a, double b) {
  ++clock_;
  for (Chirps& c : cache_)
    if (c.used > 0 && c.columns == columns && c.a == a && c.b == b) {
      c.used = clock_;
      return c;
    }
  Chirps& c = *std::min_element(cache_.begin(), cache_.end(), [](const Chirps& x, const Chirps& y) { return x.used < y.used; });
  c.columns = columns, c.a = a, c.b = b, c.used = clock_;
  const double k = 2 * std::numbers::pi / m_;
  const int l = columns ? l_columns_ : l_rows_;
  // The kernel's chirp at lags d and its transform, in double whatever Real is.
  AlignedBuffer buffer(static_cast<std::size_t>(l) * sizeof(fftw_complex));
  auto* w = static_cast<std::complex<double>*>(buffer.data());
  std::fill(w, w + l, std::complex<double>(0, 0));
  if (columns) {
    // Coefficient i holds frequency i - M/2 (i = 0 .. M); output j reads lag j - i + M/2, at
    // circular index j + M - i (never wrapping for j < S, as L >= M + S).
    c.pre.resize(static_cast<std::size_t>(m_) + 1);
    for (int i = 0; i <= m_; ++i) {
      const int q = i - m_ / 2;
      const double weight = (i == 0 || i == m_ ? 0.5 : 1.0) * m_;
      c.pre[i] = Complex(std::polar(weight, k * (q * a + 0.5 * b * q * q)));
    }
    for (int e = 0; e < m_ + s_; ++e) {
      const double d = e - m_ / 2;
      w[e] = std::polar(1.0, -k * 0.5 * b * d * d);
    }
  } else {
    // Coefficient q (0 .. M/2); output j reads lag j - q at circular index (j - q) mod L.
    c.pre.resize(static_cast<std::size_t>(h_));
    for (int q = 0; q < h_; ++q) {
      const double wq = (q == 0 || q == m_ / 2 ? 1.0 : 2.0) / m_;
      c.pre[q] = Complex(std::polar(wq, k * (q * a + 0.5 * b * q * q)));
    }
    for (int j = -(h_ - 1); j < s_; ++j) w[(j + l) % l] = std::polar(1.0, -k * 0.5 * b * j * j);
  }
  {
    fftw_plan plan;
    {
      std::lock_guard<std::mutex> lock(fftw_planner_mutex());
      plan = fftw_plan_dft_1d(l, reinterpret_cast<fftw_complex*>(w), reinterpret_cast<fftw_complex*>(w), FFTW_FORWARD,
                              FFTW_ESTIMATE);
    }
    if (!plan) throw std::runtime_error("ChirpResampler: FFTW could not plan " + std::to_string(l) + " points");
    fftw_execute(plan);
    std::lock_guard<std::mutex> lock(fftw_planner_mutex());
    fftw_destroy_plan(plan);
  }
  c.kernel.resize(static_cast<std::size_t>(l));
  for (int i = 0; i < l; ++i) c.kernel[i] = Complex(w[i]);
  c.post.resize(static_cast<std::size_t>(s_));
  for (int j = 0; j < s_; ++j) c.post[j] = Complex(std::polar(1.0 / l, k * 0.5 * b * j * j));
  return c;
}

template <class Real>
void BasicChirpResampler<Real>::resample(const Complex* rows, int n, double a, double b, Real* out, int out_stride) {
  const Chirps& c = chirps_for(false, a, b);
  auto* w = static_cast<Complex*>(rows_work_.data());
  for (int r = 0; r < n; ++r) {
    const Complex* f = rows + static_cast<std::size_t>(r) * h_;
    kernels::complex_product(f, c.pre.data(), w, static_cast<std::size_t>(h_));
    std::fill(w + h_, w + l_rows_, Complex(0, 0));
    Fftw<Real>::execute(rows_forward_);
    kernels::complex_scale(w, c.kernel.data(), static_cast<std::size_t>(l_rows_));
    Fftw<Real>::execute(rows_backward_);
    Real* o = out + static_cast<std::size_t>(r) * out_stride;
    const Real* wd = reinterpret_cast<const Real*>(w);
    const Real* pd = reinterpret_cast<const Real*>(c.post.data());
    for (int j = 0; j < s_; ++j) o[j] = wd[2 * j] * pd[2 * j] - wd[2 * j + 1] * pd[2 * j + 1];
  }
}

template <class Real>
void BasicChirpResampler<Real>::resample_columns(const Complex* columns, int n, int stride, double a, double b,
                                                 Complex* out, int out_stride) {
  const Chirps& c = chirps_for(true, a, b);
  auto* w = static_cast<Complex*>(columns_work_.data());
  const Real* pre = reinterpret_cast<const Real*>(c.pre.data());
  const Real* post = reinterpret_cast<const Real*>(c.post.data());
  const int half = m_ / 2;
  for (int col = 0; col < n; ++col) {
    Real* wd = reinterpret_cast<Real*>(w);
    for (int i = 0; i <= m_; ++i) {
      const int k = i < half ? i + half : i - half;  // frequency i - M/2 stored at (i - M/2) mod M
      const Real* f = reinterpret_cast<const Real*>(columns + static_cast<std::size_t>(k) * stride + col);
      wd[2 * i] = f[0] * pre[2 * i] - f[1] * pre[2 * i + 1];
      wd[2 * i + 1] = f[0] * pre[2 * i + 1] + f[1] * pre[2 * i];
    }
    std::fill(w + m_ + 1, w + l_columns_, Complex(0, 0));
    Fftw<Real>::execute(columns_forward_);
    kernels::complex_scale(w, c.kernel.data(), static_cast<std::size_t>(l_columns_));
    Fftw<Real>::execute(columns_backward_);
    for (int j = 0; j < s_; ++j) {
      const Real yr = wd[2 * (j + m_)], yi = wd[2 * (j + m_) + 1];
      Real* o = reinterpret_cast<Real*>(out + static_cast<std::size_t>(j) * out_stride + col);
      o[0] = yr * post[2 * j] - yi * post[2 * j + 1];
      o[1] = yr * post[2 * j + 1] + yi * post[2 * j];
    }
  }
}

template class BasicChirpResampler<double>;
template class BasicChirpResampler<float>;

}  // namespace stampede
