// Metacalibration's image operations; see metacal_imager.hpp.
#include "engine/metacal/metacal_imager.hpp"

#include <fftw3.h>

#include <Eigen/Core>
#include <algorithm>
#include <cmath>
#include <mutex>
#include <numbers>
#include <stdexcept>

#include "kernels/math/blocked_loop.hpp"
#include "kernels/math/complex_product.hpp"
#include "kernels/math/phasors.hpp"

namespace stampede {
namespace {

using RowMatrix = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;

bool fft_friendly(int n) {
  for (int p : {2, 3, 5, 7})
    while (n % p == 0) n /= p;
  return n == 1;
}

unsigned plan_flags(FftPlanning p) { return p == FftPlanning::kMeasure ? FFTW_MEASURE : FFTW_ESTIMATE; }

}  // namespace

int MetacalImager::padded_size(int stamp_size) { return padded_size(std::max(stamp_size, 2), std::max(stamp_size, 2) / 2); }

int MetacalImager::padded_size(int stamp_size, int margin) {
  int n = stamp_size + 2 * margin;
  n += n % 2;
  while (!fft_friendly(n)) n += 2;
  return n;
}

MetacalImager::MetacalImager(int stamp_size, int period, FftPlanning planning)
    : s_(stamp_size), m_(period), h_count_(period / 2 + 1), offset_((period - stamp_size) / 2) {
  if (stamp_size < 1 || period < stamp_size || period % 2 != 0)
    throw std::invalid_argument("MetacalImager: period must be even and >= the stamp size");
  const std::size_t real = static_cast<std::size_t>(m_) * m_ * sizeof(double);
  const std::size_t cplx = static_cast<std::size_t>(m_) * h_count_ * sizeof(fftw_complex);
  padded_ = AlignedBuffer(real);
  h_ = AlignedBuffer(real);
  grid_ = AlignedBuffer(real);
  transposed_ = AlignedBuffer(real);
  spectrum_ = AlignedBuffer(cplx);
  work_spectrum_ = AlignedBuffer(cplx);
  rows_spectrum_ = AlignedBuffer(cplx);
  auto* pad = static_cast<double*>(padded_.data());
  auto* h = static_cast<double*>(h_.data());
  auto* grid = static_cast<double*>(grid_.data());
  auto* spec = static_cast<fftw_complex*>(spectrum_.data());
  auto* work = static_cast<fftw_complex*>(work_spectrum_.data());
  auto* rows = static_cast<fftw_complex*>(rows_spectrum_.data());
  const unsigned flags = plan_flags(planning);
  {
    std::lock_guard<std::mutex> lock(fftw_planner_mutex());
    forward_2d_ = fftw_plan_dft_r2c_2d(m_, m_, pad, spec, flags);
    backward_2d_ = fftw_plan_dft_c2r_2d(m_, m_, work, h, flags | FFTW_DESTROY_INPUT);
    const int n[1] = {m_};
    rows_forward_ = fftw_plan_many_dft_r2c(1, n, m_, grid, nullptr, 1, m_, rows, nullptr, 1, h_count_, flags);
    stamp_rows_forward_ = fftw_plan_many_dft_r2c(1, n, s_, grid, nullptr, 1, m_, rows, nullptr, 1, h_count_, flags);
    rows_backward_ =
        fftw_plan_many_dft_c2r(1, n, m_, rows, nullptr, 1, h_count_, grid, nullptr, 1, m_, flags | FFTW_DESTROY_INPUT);
  }
  if (!forward_2d_ || !backward_2d_ || !rows_forward_ || !stamp_rows_forward_ || !rows_backward_)
    throw std::runtime_error("MetacalImager: FFTW could not plan a " + std::to_string(m_) + "-point grid");
  // Planning with FFTW_MEASURE overwrites the arrays.
  std::fill(pad, pad + static_cast<std::size_t>(m_) * m_, 0.0);
  weight_cache_.resize(kWeightSlots);
  positions_.resize(s_);
  phasors_.resize(h_count_);
  phases_.resize(static_cast<std::size_t>(kRotateRows) * h_count_);
  scratch_.resize(static_cast<std::size_t>(m_) * s_);
  scratch_t_.resize(static_cast<std::size_t>(m_) * s_);
  if (s_ >= kChirpMinStamp) chirp_ = std::make_unique<ChirpResampler>(m_, s_, planning);
}

MetacalImager::~MetacalImager() {
  std::lock_guard<std::mutex> lock(fftw_planner_mutex());
  for (void* p : {forward_2d_, backward_2d_, rows_forward_, stamp_rows_forward_, rows_backward_})
    if (p) fftw_destroy_plan(static_cast<fftw_plan>(p));
}

void MetacalImager::make_images(std::span<const double> stamp, const MetacalFilters& filters, double centre_x,
                                double centre_y, std::span<double> out) {
  const std::size_t npix = static_cast<std::size_t>(s_) * s_;
  if (stamp.size() != npix || out.size() != kNumMetacalTypes * npix || filters.period() != m_)
    throw std::invalid_argument("MetacalImager::make_images: sizes do not match the imager");
  auto* pad = static_cast<double*>(padded_.data());
  for (int y = 0; y < s_; ++y)
    std::copy_n(stamp.data() + static_cast<std::size_t>(y) * s_, s_, pad + static_cast<std::size_t>(offset_ + y) * m_ + offset_);
  fftw_execute(static_cast<fftw_plan>(forward_2d_));
  const double cx = offset_ + centre_x, cy = offset_ + centre_y;  // padded-grid coordinates
  const auto* h = static_cast<const double*>(h_.data());
  for (MetacalType t : kMetacalTypes) {
    double* img = out.data() + static_cast<int>(t) * npix;
    filtered(filters.filter(t));
    const std::array<double, 4>& b = filters.inverse_shear(t);
    if (t == MetacalType::kNoshear) {
      for (int y = 0; y < s_; ++y)
        std::copy_n(h + static_cast<std::size_t>(offset_ + y) * m_ + offset_, s_, img + static_cast<std::size_t>(y) * s_);
    } else if (b[1] == 0.0 && b[2] == 0.0) {
      scaled(b[0], b[3], cx, cy, img);
    } else if (b[1] == b[2] && b[0] == b[3]) {
      sheared(b[0], b[1], cx, cy, img);
    } else {
      general(b, cx, cy, img);
    }
  }
}

void MetacalImager::filtered(const std::complex<double>* f) {
  const auto* spec = static_cast<const std::complex<double>*>(spectrum_.data());
  auto* work = static_cast<std::complex<double>*>(work_spectrum_.data());
  kernels::complex_product(spec, f, work, static_cast<std::size_t>(m_) * h_count_);
  fftw_execute(static_cast<fftw_plan>(backward_2d_));
}

void MetacalImager::dft_weights(std::span<const double> positions, std::vector<double>* w) {
  const std::size_t n = positions.size();
  w->assign(static_cast<std::size_t>(2 * h_count_) * n, 0.0);
  for (std::size_t j = 0; j < n; ++j) {
    kernels::phasors(0.0, 2 * std::numbers::pi * positions[j] / m_, h_count_, phasors_.data());
    for (int q = 0; q < h_count_; ++q) {
      const double wq = (q == 0 || q == m_ / 2 ? 1.0 : 2.0) / m_;
      (*w)[static_cast<std::size_t>(2 * q) * n + j] = wq * phasors_[q].real();
      (*w)[static_cast<std::size_t>(2 * q + 1) * n + j] = -wq * phasors_[q].imag();
    }
  }
}

const double* MetacalImager::weights_for(std::span<const double> positions) {
  ++clock_;
  for (CachedWeights& c : weight_cache_)
    if (std::equal(positions.begin(), positions.end(), c.positions.begin(), c.positions.end())) {
      c.used = clock_;
      return c.weights.data();
    }
  CachedWeights& slot = *std::min_element(weight_cache_.begin(), weight_cache_.end(),
                                          [](const CachedWeights& a, const CachedWeights& b) { return a.used < b.used; });
  slot.positions.assign(positions.begin(), positions.end());
  dft_weights(positions, &slot.weights);
  slot.used = clock_;
  return slot.weights.data();
}

void MetacalImager::transpose(const double* in, double* out, int rows, int cols) {
  kernels::for_each_blocked(rows, cols, [&](int r, int c) {
    out[static_cast<std::size_t>(c) * rows + r] = in[static_cast<std::size_t>(r) * cols + c];
  });
}

void MetacalImager::scaled(double b0, double b1, double cx, double cy, double* out) {
  auto* rows = static_cast<double*>(rows_spectrum_.data());
  auto* grid = static_cast<double*>(grid_.data());
  const int two_h = 2 * h_count_;
  // Rows: every padded row at the stamp's columns, stretched about cx (the r2c keeps its input).
  fftw_execute_dft_r2c(static_cast<fftw_plan>(rows_forward_), static_cast<double*>(h_.data()),
                       reinterpret_cast<fftw_complex*>(rows));
  const auto* spectra = reinterpret_cast<const std::complex<double>*>(rows);
  if (chirp_) {
    chirp_->resample(spectra, m_, cx + b0 * (offset_ - cx), b0, scratch_.data(), s_);
    transpose(scratch_.data(), grid, m_, s_);
    fftw_execute_dft_r2c(static_cast<fftw_plan>(rows_forward_), grid, reinterpret_cast<fftw_complex*>(rows));
    chirp_->resample(spectra, s_, cy + b1 * (offset_ - cy), b1, scratch_t_.data(), s_);
    transpose(scratch_t_.data(), out, s_, s_);
    return;
  }
  for (int j = 0; j < s_; ++j) positions_[j] = cx + b0 * (offset_ + j - cx);
  Eigen::Map<RowMatrix> by_row(scratch_.data(), m_, s_);
  by_row.noalias() = Eigen::Map<const RowMatrix>(rows, m_, two_h) * Eigen::Map<const RowMatrix>(weights_for(positions_), two_h, s_);
  // Columns: the stamp's columns, as rows of the transpose, at the stamp's rows stretched about cy.
  transpose(scratch_.data(), grid, m_, s_);  // s_ rows of m_ (the rest of grid is not read)
  fftw_execute_dft_r2c(static_cast<fftw_plan>(rows_forward_), grid, reinterpret_cast<fftw_complex*>(rows));
  for (int i = 0; i < s_; ++i) positions_[i] = cy + b1 * (offset_ + i - cy);
  Eigen::Map<RowMatrix> by_column(scratch_t_.data(), s_, s_);  // [x][y]
  by_column.noalias() = Eigen::Map<const RowMatrix>(rows, s_, two_h) * Eigen::Map<const RowMatrix>(weights_for(positions_), two_h, s_);
  transpose(scratch_t_.data(), out, s_, s_);
}

void MetacalImager::rotate_rows(std::complex<double>* const* rows, const std::complex<double>* steps, int count,
                                std::complex<double> phase, int n) {
  // rows[k][q] *= phase steps[k]^q, the powers by repeated products (as std::complex's, without
  // its NaN checks), the rows' recurrences side by side (each is a chain of dependent products),
  // into the phase buffer; then one vectorised product per row.
  double pr[kRotateRows], pi[kRotateRows], sr[kRotateRows], si[kRotateRows];
  double* p[kRotateRows];
  for (int k = 0; k < kRotateRows; ++k) {
    const int j = k < count ? k : 0;
    pr[k] = phase.real(), pi[k] = phase.imag(), sr[k] = steps[j].real(), si[k] = steps[j].imag();
    p[k] = reinterpret_cast<double*>(phases_.data() + static_cast<std::size_t>(k) * h_count_);
  }
  for (int q = 0; q < n; ++q)
    for (int k = 0; k < kRotateRows; ++k) {
      p[k][2 * q] = pr[k], p[k][2 * q + 1] = pi[k];
      const double nr = pr[k] * sr[k] - pi[k] * si[k], ni = pr[k] * si[k] + pi[k] * sr[k];
      pr[k] = nr, pi[k] = ni;
    }
  for (int k = 0; k < count; ++k)
    kernels::complex_scale(rows[k], phases_.data() + static_cast<std::size_t>(k) * h_count_, static_cast<std::size_t>(n));
}

template <class Shift>
void MetacalImager::shift_rows(double* grid, Shift shift) {
  auto* rows = static_cast<std::complex<double>*>(rows_spectrum_.data());
  fftw_execute_dft_r2c(static_cast<fftw_plan>(rows_forward_), grid, reinterpret_cast<fftw_complex*>(rows));
  const double inv = 1.0 / m_;
  std::complex<double>* group[kRotateRows];
  std::complex<double> steps[kRotateRows];
  for (int r0 = 0; r0 < m_; r0 += kRotateRows) {
    const int count = std::min(kRotateRows, m_ - r0);
    for (int k = 0; k < count; ++k) {
      const int r = r0 + k;
      const double t = shift(r);
      group[k] = rows + static_cast<std::size_t>(r) * h_count_;
      steps[k] = std::polar(1.0, 2 * std::numbers::pi * t / m_);
      // The Nyquist term of a real row is cos(pi (x + t)) times a real coefficient: at integer
      // x only its cos(pi t) part survives.
      group[k][m_ / 2] *= inv * std::cos(std::numbers::pi * t);
    }
    rotate_rows(group, steps, count, std::complex<double>(inv, 0.0), m_ / 2);
  }
  fftw_execute_dft_c2r(static_cast<fftw_plan>(rows_backward_), reinterpret_cast<fftw_complex*>(rows), grid);
}

void MetacalImager::sheared(double a, double b, double cx, double cy, double* out) {
  // [[a, b], [b, a]] = X(s) Y(b) X(s) with X(s) = [[1, s], [0, 1]], Y(b) = [[1, 0], [b, 1]] and
  // s = (a - 1) / b; H(c + X Y X u) is three one-axis shifts, the last applied first to H.
  const double s = (a - 1) / b;
  auto* grid = static_cast<double*>(grid_.data());
  auto* transposed = static_cast<double*>(transposed_.data());
  // The coordinate of padded index i about centre c, on the periodic grid: in [-M/2, M/2).
  auto centred = [&](int i, double c) {
    double d = i - c;
    if (d >= 0.5 * m_) d -= m_;
    if (d < -0.5 * m_) d += m_;
    return d;
  };
  std::copy_n(static_cast<const double*>(h_.data()), static_cast<std::size_t>(m_) * m_, grid);
  shift_rows(grid, [&](int r) { return s * centred(r, cy); });          // F1(x, y) = H(x + s y, y)
  transpose(grid, transposed, m_, m_);
  shift_rows(transposed, [&](int c) { return b * centred(c, cx); });           // F2(x, y) = F1(x, y + b x)
  transpose(transposed, grid, m_, m_);
  shift_rows(grid, [&](int r) { return s * centred(r, cy); });          // R(x, y) = F2(x + s y, y)
  for (int y = 0; y < s_; ++y)
    std::copy_n(grid + static_cast<std::size_t>(offset_ + y) * m_ + offset_, s_, out + static_cast<std::size_t>(y) * s_);
}

template <class Shift>
void MetacalImager::ramp_rows(int n, Shift shift) {
  auto* rows = static_cast<std::complex<double>*>(rows_spectrum_.data());
  std::complex<double>* group[kRotateRows];
  std::complex<double> steps[kRotateRows];
  for (int r0 = 0; r0 < n; r0 += kRotateRows) {
    const int count = std::min(kRotateRows, n - r0);
    for (int k = 0; k < count; ++k) {
      group[k] = rows + static_cast<std::size_t>(r0 + k) * h_count_;
      steps[k] = std::polar(1.0, 2 * std::numbers::pi * shift(r0 + k) / m_);
    }
    rotate_rows(group, steps, count, std::complex<double>(1.0, 0.0), h_count_);
  }
}

void MetacalImager::general(const std::array<double, 4>& b, double cx, double cy, double* out) {
  // B = L D X with L = [[1, 0], [l, 1]], D = diag(d1, d2), X = [[1, u / d1], [0, 1]]:
  // H(c + B (x - c)) = F(c + D X (x - c)) with F(x, y) = H(x, y + l (x - cx)), i.e.
  //   G(x, y) = F(x, cy + d2 (y - cy))                     (every column: shift, then stretch)
  //   out(x, y) = G(cx + d1 (x - cx) + u (y - cy), y)      (the stamp's rows: shift, then stretch)
  const double d1 = b[0], u = b[1], l = b[2] / b[0], d2 = b[3] - l * b[1];
  auto* rows = static_cast<double*>(rows_spectrum_.data());
  auto* grid = static_cast<double*>(grid_.data());
  auto* transposed = static_cast<double*>(transposed_.data());
  const int two_h = 2 * h_count_;
  auto centred = [&](int i, double c) {  // periodic coordinate about c, in [-M/2, M/2)
    double d = i - c;
    if (d >= 0.5 * m_) d -= m_;
    if (d < -0.5 * m_) d += m_;
    return d;
  };
  // Columns (as rows of the transpose): column x read at y + l (x - cx), at the stretched rows of
  // the stamp alone (the second pass reads no other row of G).
  transpose(static_cast<const double*>(h_.data()), transposed, m_, m_);
  fftw_execute_dft_r2c(static_cast<fftw_plan>(rows_forward_), transposed, reinterpret_cast<fftw_complex*>(rows));
  ramp_rows(m_, [&](int x) { return l * centred(x, cx); });
  for (int j = 0; j < s_; ++j) positions_[j] = cy + d2 * centred(offset_ + j, cy);
  Eigen::Map<RowMatrix>(grid, m_, s_).noalias() =
      Eigen::Map<const RowMatrix>(rows, m_, two_h) * Eigen::Map<const RowMatrix>(weights_for(positions_), two_h, s_);
  transpose(grid, transposed, m_, s_);  // G at the stamp's rows y, each a row of M
  // The stamp's rows: row y read at x + u (y - cy), at the stretched columns.
  fftw_execute_dft_r2c(static_cast<fftw_plan>(stamp_rows_forward_), transposed, reinterpret_cast<fftw_complex*>(rows));
  ramp_rows(s_, [&](int i) { return u * centred(offset_ + i, cy); });
  for (int j = 0; j < s_; ++j) positions_[j] = cx + d1 * centred(offset_ + j, cx);
  Eigen::Map<RowMatrix>(out, s_, s_).noalias() =
      Eigen::Map<const RowMatrix>(rows, s_, two_h) * Eigen::Map<const RowMatrix>(weights_for(positions_), two_h, s_);
}

}  // namespace stampede
