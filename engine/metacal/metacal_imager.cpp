// Metacalibration's image operations; see metacal_imager.hpp.
#include "engine/metacal/metacal_imager.hpp"

#include <Eigen/Core>
#include <algorithm>
#include <cmath>
#include <mutex>
#include <numbers>
#include <stdexcept>
#include <type_traits>

#include "engine/common/fftw_precision.hpp"
#include "kernels/math/blocked_loop.hpp"
#include "kernels/math/complex_product.hpp"
#include "kernels/math/phasors.hpp"

namespace stampede {
namespace {

template <class Real>
using RowMatrix = Eigen::Matrix<Real, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;

bool fft_friendly(int n) {
  for (int p : {2, 3, 5, 7})
    while (n % p == 0) n /= p;
  return n == 1;
}

unsigned plan_flags(FftPlanning p) { return p == FftPlanning::kMeasure ? FFTW_MEASURE : FFTW_ESTIMATE; }

}  // namespace

template <class Real>
int BasicMetacalImager<Real>::padded_size(int stamp_size) {
  return padded_size(std::max(stamp_size, 2), std::max(stamp_size, 2) / 2);
}

template <class Real>
int BasicMetacalImager<Real>::padded_size(int stamp_size, int margin) {
  int n = stamp_size + 2 * margin;
  n += n % 2;
  while (!fft_friendly(n)) n += 2;
  return n;
}

template <class Real>
BasicMetacalImager<Real>::BasicMetacalImager(int stamp_size, int period, FftPlanning planning)
    : s_(stamp_size), m_(period), h_count_(period / 2 + 1), offset_((period - stamp_size) / 2) {
  using F = Fftw<Real>;
  if (stamp_size < 1 || period < stamp_size || period % 2 != 0)
    throw std::invalid_argument("MetacalImager: period must be even and >= the stamp size");
  const std::size_t real = static_cast<std::size_t>(m_) * m_ * sizeof(Real);
  const std::size_t cplx = static_cast<std::size_t>(m_) * h_count_ * sizeof(Complex);
  padded_ = AlignedBuffer(real);
  h_ = AlignedBuffer(real);
  grid_ = AlignedBuffer(real);
  transposed_ = AlignedBuffer(real);
  spectrum_ = AlignedBuffer(cplx);
  turned_spectrum_ = AlignedBuffer(cplx);
  work_spectrum_ = AlignedBuffer(cplx);
  rows_spectrum_ = AlignedBuffer(cplx);
  auto* pad = static_cast<Real*>(padded_.data());
  auto* h = static_cast<Real*>(h_.data());
  auto* grid = static_cast<Real*>(grid_.data());
  auto* spec = F::c(static_cast<Complex*>(spectrum_.data()));
  auto* work = F::c(static_cast<Complex*>(work_spectrum_.data()));
  auto* rows = F::c(static_cast<Complex*>(rows_spectrum_.data()));
  const bool cell = s_ >= kChirpMinStamp;
  const unsigned flags = plan_flags(planning);
  {
    std::lock_guard<std::mutex> lock(fftw_planner_mutex());
    forward_2d_ = F::r2c_2d(m_, m_, pad, spec, flags);
    backward_2d_ = F::c2r_2d(m_, m_, work, h, flags | FFTW_DESTROY_INPUT);
    const int n[1] = {m_};
    rows_forward_ = F::many_r2c(1, n, m_, grid, 1, m_, rows, 1, h_count_, flags);
    stamp_rows_forward_ = F::many_r2c(1, n, s_, grid, 1, m_, rows, 1, h_count_, flags);
    rows_backward_ = F::many_c2r(1, n, m_, rows, 1, h_count_, grid, 1, m_, flags | FFTW_DESTROY_INPUT);
    if (cell) {
      Real* window = grid + static_cast<std::size_t>(offset_) * m_;
      columns_backward_ = F::many_c2c(1, n, h_count_, work, h_count_, 1, work, h_count_, 1, FFTW_BACKWARD, flags);
      window_rows_forward_ = F::many_r2c(1, n, s_, window, 1, m_, rows, 1, h_count_, flags);
      window_rows_backward_ = F::many_c2r(1, n, s_, rows, 1, h_count_, window, 1, m_, flags | FFTW_DESTROY_INPUT);
    }
  }
  if (!forward_2d_ || !backward_2d_ || !rows_forward_ || !stamp_rows_forward_ || !rows_backward_ ||
      (cell && (!columns_backward_ || !window_rows_forward_ || !window_rows_backward_)))
    throw std::runtime_error("MetacalImager: FFTW could not plan a " + std::to_string(m_) + "-point grid");
  // Planning with FFTW_MEASURE overwrites the arrays.
  std::fill(pad, pad + static_cast<std::size_t>(m_) * m_, Real(0));
  weight_cache_.resize(kWeightSlots);
  positions_.resize(s_);
  phasors_.resize(h_count_);
  phases_.resize(static_cast<std::size_t>(kRotateRows) * h_count_);
  shift_tables_.resize(kShiftSlots);
  scratch_.resize(static_cast<std::size_t>(m_) * s_);
  scratch_t_.resize(static_cast<std::size_t>(m_) * s_);
  if (cell) chirp_ = std::make_unique<BasicChirpResampler<Real>>(m_, s_, planning);
}

template <class Real>
BasicMetacalImager<Real>::~BasicMetacalImager() {
  std::lock_guard<std::mutex> lock(fftw_planner_mutex());
  for (void* p : {forward_2d_, backward_2d_, rows_forward_, stamp_rows_forward_, rows_backward_, columns_backward_,
                  window_rows_forward_, window_rows_backward_})
    if (p) Fftw<Real>::destroy(p);
}

template <class Real>
void BasicMetacalImager<Real>::make_images(std::span<const double> stamp, const MetacalFilters& filters, double centre_x,
                                           double centre_y, std::span<double> out, std::span<const double> turned) {
  const std::size_t npix = static_cast<std::size_t>(s_) * s_;
  if (stamp.size() != npix || out.size() != kNumMetacalTypes * npix || filters.period() != m_ ||
      (!turned.empty() && turned.size() != npix))
    throw std::invalid_argument("MetacalImager::make_images: sizes do not match the imager");
  using FC = typename Fftw<Real>::Complex;
  auto* pad = static_cast<Real*>(padded_.data());
  auto transform = [&](std::span<const double> in, AlignedBuffer& spectrum) {
    for (int y = 0; y < s_; ++y)
      std::copy_n(in.data() + static_cast<std::size_t>(y) * s_, s_, pad + static_cast<std::size_t>(offset_ + y) * m_ + offset_);
    Fftw<Real>::execute_r2c(forward_2d_, pad, reinterpret_cast<FC*>(spectrum.data()));
  };
  transform(stamp, spectrum_);
  if (!turned.empty()) transform(turned, turned_spectrum_);
  const double cx = offset_ + centre_x, cy = offset_ + centre_y;  // padded-grid coordinates
  // Type by type, the stamp's image stored and the turned stamp's added to it while it is in cache.
  for (MetacalType t : kMetacalTypes) {
    double* img = out.data() + static_cast<int>(t) * npix;
    add_rotated_back_ = false;
    image(static_cast<const Complex*>(spectrum_.data()), filters, t, cx, cy, img);
    if (turned.empty()) continue;
    add_rotated_back_ = true;
    image(static_cast<const Complex*>(turned_spectrum_.data()), filters, t, cx, cy, img);
  }
}

template <class Real>
void BasicMetacalImager<Real>::image(const Complex* spectrum, const MetacalFilters& filters, MetacalType t, double cx,
                                     double cy, double* img) {
  const std::array<double, 4>& b = filters.inverse_shear(t);
  if (t == MetacalType::kNoshear) {
    filtered(spectrum, filters, t);
    emit(window(static_cast<const Real*>(h_.data())), m_, 1, img);
  } else if (b[1] == 0.0 && b[2] == 0.0) {
    if (chirp_) {
      filter_spectrum(spectrum, filters, t);
      scaled_from_spectrum(b[0], b[3], cx, cy, img);
    } else {
      filtered(spectrum, filters, t);
      scaled(b[0], b[3], cx, cy, img);
    }
  } else if (b[1] == b[2] && b[0] == b[3]) {
    if (chirp_)
      filter_spectrum(spectrum, filters, t);
    else
      filtered(spectrum, filters, t);
    sheared(b[0], b[1], cx, cy, img);
  } else {
    filtered(spectrum, filters, t);
    general(b, cx, cy, img);
  }
}

template <class Real>
void BasicMetacalImager<Real>::filter_spectrum(const Complex* spec, const MetacalFilters& filters, MetacalType t) {
  auto* work = static_cast<Complex*>(work_spectrum_.data());
  const std::size_t n = static_cast<std::size_t>(m_) * h_count_;
  if constexpr (std::is_same_v<Real, float>)
    kernels::complex_product(spec, filters.single_filter(t), work, n);
  else
    kernels::complex_product(spec, filters.filter(t), work, n);
}

template <class Real>
void BasicMetacalImager<Real>::filtered(const Complex* spectrum, const MetacalFilters& filters, MetacalType t) {
  filter_spectrum(spectrum, filters, t);
  Fftw<Real>::execute(backward_2d_);
}

template <class Real>
void BasicMetacalImager<Real>::emit(const Real* src, int row_stride, int column_stride, double* out) const {
  const int s = s_;
  if (add_rotated_back_) {
    kernels::for_each_blocked(s, s, [&](int y, int x) {
      out[static_cast<std::size_t>(y) * s + x] += src[static_cast<std::size_t>(x) * row_stride + static_cast<std::size_t>(s - 1 - y) * column_stride];
    });
  } else if (column_stride == 1) {
    for (int y = 0; y < s; ++y)
      std::copy_n(src + static_cast<std::size_t>(y) * row_stride, s, out + static_cast<std::size_t>(y) * s);
  } else {
    kernels::for_each_blocked(s, s, [&](int y, int x) {
      out[static_cast<std::size_t>(y) * s + x] = src[static_cast<std::size_t>(y) * row_stride + static_cast<std::size_t>(x) * column_stride];
    });
  }
}

template <class Real>
void BasicMetacalImager<Real>::dft_weights(std::span<const double> positions, std::vector<Real>* w) {
  const std::size_t n = positions.size();
  w->assign(static_cast<std::size_t>(2 * h_count_) * n, Real(0));
  for (std::size_t j = 0; j < n; ++j) {
    kernels::phasors(0.0, 2 * std::numbers::pi * positions[j] / m_, h_count_, phasors_.data());
    for (int q = 0; q < h_count_; ++q) {
      const double wq = (q == 0 || q == m_ / 2 ? 1.0 : 2.0) / m_;
      (*w)[static_cast<std::size_t>(2 * q) * n + j] = static_cast<Real>(wq * phasors_[q].real());
      (*w)[static_cast<std::size_t>(2 * q + 1) * n + j] = static_cast<Real>(-wq * phasors_[q].imag());
    }
  }
}

template <class Real>
const Real* BasicMetacalImager<Real>::weights_for(std::span<const double> positions) {
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

template <class Real>
void BasicMetacalImager<Real>::transpose(const Real* in, int in_stride, Real* out, int out_stride, int rows, int cols) {
  kernels::for_each_blocked(rows, cols, [&](int r, int c) {
    out[static_cast<std::size_t>(c) * out_stride + r] = in[static_cast<std::size_t>(r) * in_stride + c];
  });
}

template <class Real>
void BasicMetacalImager<Real>::scaled(double b0, double b1, double cx, double cy, double* out) {
  using F = Fftw<Real>;
  auto* rows = reinterpret_cast<Real*>(rows_spectrum_.data());
  auto* grid = static_cast<Real*>(grid_.data());
  const int two_h = 2 * h_count_;
  // Rows: every padded row at the stamp's columns, stretched about cx (the r2c keeps its input).
  F::execute_r2c(rows_forward_, static_cast<Real*>(h_.data()), reinterpret_cast<typename F::Complex*>(rows));
  for (int j = 0; j < s_; ++j) positions_[j] = cx + b0 * (offset_ + j - cx);
  Eigen::Map<RowMatrix<Real>> by_row(scratch_.data(), m_, s_);
  by_row.noalias() =
      Eigen::Map<const RowMatrix<Real>>(rows, m_, two_h) * Eigen::Map<const RowMatrix<Real>>(weights_for(positions_), two_h, s_);
  // Columns: the stamp's columns, as rows of the transpose, at the stamp's rows stretched about cy.
  transpose(scratch_.data(), s_, grid, m_, m_, s_);  // s_ rows of m_ (the rest of grid is not read)
  F::execute_r2c(rows_forward_, grid, reinterpret_cast<typename F::Complex*>(rows));
  for (int i = 0; i < s_; ++i) positions_[i] = cy + b1 * (offset_ + i - cy);
  Eigen::Map<RowMatrix<Real>> by_column(scratch_t_.data(), s_, s_);  // [x][y]
  by_column.noalias() =
      Eigen::Map<const RowMatrix<Real>>(rows, s_, two_h) * Eigen::Map<const RowMatrix<Real>>(weights_for(positions_), two_h, s_);
  emit(scratch_t_.data(), 1, s_, out);
}

template <class Real>
void BasicMetacalImager<Real>::scaled_from_spectrum(double b0, double b1, double cx, double cy, double* out) {
  auto* work = static_cast<const Complex*>(work_spectrum_.data());
  auto* rows = static_cast<Complex*>(rows_spectrum_.data());
  // The spectrum's columns at the stamp's rows stretched about cy: each row's half spectrum, as an
  // r2c of H's row would give it. Its q = 0 and M/2 terms are real there (the c2r the stamps' path
  // takes drops their imaginary parts, which only the grid's Nyquist edge gives).
  chirp_->resample_columns(work, h_count_, h_count_, cy + b1 * (offset_ - cy), b1, rows, h_count_);
  for (int j = 0; j < s_; ++j) {
    Complex* row = rows + static_cast<std::size_t>(j) * h_count_;
    row[0].imag(0), row[m_ / 2].imag(0);
  }
  // Those rows at the stamp's columns stretched about cx.
  chirp_->resample(rows, s_, cx + b0 * (offset_ - cx), b0, scratch_.data(), s_);
  emit(scratch_.data(), s_, 1, out);
}

template <class Real>
void BasicMetacalImager<Real>::fill_phases(Complex* const* dest, const std::complex<double>* steps, int count,
                                           double phase, int n) {
  // The powers by repeated products in double (as std::complex's, without its NaN checks), the
  // rows' recurrences side by side (each is a chain of dependent products).
  double pr[kRotateRows], pi[kRotateRows], sr[kRotateRows], si[kRotateRows];
  Real* p[kRotateRows];
  for (int k = 0; k < kRotateRows; ++k) {
    const int j = k < count ? k : 0;
    pr[k] = phase, pi[k] = 0.0, sr[k] = steps[j].real(), si[k] = steps[j].imag();
    p[k] = reinterpret_cast<Real*>(k < count ? dest[k] : phases_.data() + static_cast<std::size_t>(k) * h_count_);
  }
  for (int q = 0; q < n; ++q)
    for (int k = 0; k < kRotateRows; ++k) {
      p[k][2 * q] = static_cast<Real>(pr[k]), p[k][2 * q + 1] = static_cast<Real>(pi[k]);
      const double nr = pr[k] * sr[k] - pi[k] * si[k], ni = pr[k] * si[k] + pi[k] * sr[k];
      pr[k] = nr, pi[k] = ni;
    }
}

template <class Real>
void BasicMetacalImager<Real>::rotate_rows(Complex* const* rows, const std::complex<double>* steps, int count,
                                           double phase, int n) {
  Complex* dest[kRotateRows] = {};
  for (int k = 0; k < count; ++k) dest[k] = phases_.data() + static_cast<std::size_t>(k) * h_count_;
  fill_phases(dest, steps, count, phase, n);
  for (int k = 0; k < count; ++k) kernels::complex_scale(rows[k], dest[k], static_cast<std::size_t>(n));
}

template <class Real>
const typename BasicMetacalImager<Real>::Complex* BasicMetacalImager<Real>::shift_table(double coef, double centre,
                                                                                       int first, int n, double scale) {
  ++clock_;
  for (ShiftTable& t : shift_tables_)
    if (t.used > 0 && t.coef == coef && t.centre == centre && t.first == first && t.n == n && t.scale == scale) {
      t.used = clock_;
      return t.factors.data();
    }
  ShiftTable& t = *std::min_element(shift_tables_.begin(), shift_tables_.end(),
                                    [](const ShiftTable& a, const ShiftTable& b) { return a.used < b.used; });
  t.coef = coef, t.centre = centre, t.first = first, t.n = n, t.scale = scale, t.used = clock_;
  t.factors.resize(static_cast<std::size_t>(n) * h_count_);
  Complex* dest[kRotateRows] = {};
  std::complex<double> steps[kRotateRows];
  for (int r0 = 0; r0 < n; r0 += kRotateRows) {
    const int count = std::min(kRotateRows, n - r0);
    for (int k = 0; k < count; ++k) {
      // The periodic coordinate of the padded index about the centre, in [-M/2, M/2).
      double d = first + r0 + k - centre;
      if (d >= 0.5 * m_) d -= m_;
      if (d < -0.5 * m_) d += m_;
      const double shift = coef * d;
      dest[k] = t.factors.data() + static_cast<std::size_t>(r0 + k) * h_count_;
      steps[k] = std::polar(1.0, 2 * std::numbers::pi * shift / m_);
      // The Nyquist term of a real row is cos(pi (x + t)) times a real coefficient: at integer
      // x only its cos(pi t) part survives.
      dest[k][m_ / 2] = Complex(static_cast<Real>(scale * std::cos(std::numbers::pi * shift)), Real(0));
    }
    fill_phases(dest, steps, count, scale, m_ / 2);
  }
  return t.factors.data();
}

template <class Real>
void BasicMetacalImager<Real>::shift_spectra(Complex* spectra, int n, double scale, double coef, double centre,
                                             int first, void* backward, Real* grid) {
  const Complex* table = shift_table(coef, centre, first, n, scale);
  kernels::complex_scale(spectra, table, static_cast<std::size_t>(n) * h_count_);
  Fftw<Real>::execute_c2r(backward, reinterpret_cast<typename Fftw<Real>::Complex*>(spectra), grid);
}

template <class Real>
void BasicMetacalImager<Real>::shift_rows(Real* grid, double coef, double centre) {
  auto* rows = static_cast<Complex*>(rows_spectrum_.data());
  Fftw<Real>::execute_r2c(rows_forward_, grid, reinterpret_cast<typename Fftw<Real>::Complex*>(rows));
  shift_spectra(rows, m_, 1.0 / m_, coef, centre, 0, rows_backward_, grid);
}

template <class Real>
void BasicMetacalImager<Real>::sheared(double a, double b, double cx, double cy, double* out) {
  // [[a, b], [b, a]] = X(s) Y(b) X(s) with X(s) = [[1, s], [0, 1]], Y(b) = [[1, 0], [b, 1]] and
  // s = (a - 1) / b; H(c + X Y X u) is three one-axis shifts, the last applied first to H.
  const double s = (a - 1) / b;
  auto* grid = static_cast<Real*>(grid_.data());
  auto* transposed = static_cast<Real*>(transposed_.data());
  if (!chirp_) {
    std::copy_n(static_cast<const Real*>(h_.data()), static_cast<std::size_t>(m_) * m_, grid);
    shift_rows(grid, s, cy);  // F1(x, y) = H(x + s y, y)
    transpose(grid, m_, transposed, m_, m_, m_);
    shift_rows(transposed, b, cx);  // F2(x, y) = F1(x, y + b x)
    transpose(transposed, m_, grid, m_, m_, m_);
    shift_rows(grid, s, cy);  // R(x, y) = F2(x + s y, y)
    emit(window(grid), m_, 1, out);
    return;
  }
  // Cells: the rows' spectra from the filtered spectrum's columns (M times an r2c of H's rows), and
  // the last pass on the stamp's rows alone.
  auto* work = static_cast<Complex*>(work_spectrum_.data());
  auto* rows = static_cast<Complex*>(rows_spectrum_.data());
  using FC = typename Fftw<Real>::Complex;
  Fftw<Real>::execute_c2c(columns_backward_, reinterpret_cast<FC*>(work), reinterpret_cast<FC*>(work));
  shift_spectra(work, m_, 1.0, s, cy, 0, rows_backward_, grid);
  transpose(grid, m_, transposed, m_, m_, m_);
  shift_rows(transposed, b, cx);
  Real* stamp_rows = grid + static_cast<std::size_t>(offset_) * m_;
  transpose(transposed + offset_, m_, stamp_rows, m_, m_, s_);
  Fftw<Real>::execute_r2c(window_rows_forward_, stamp_rows, reinterpret_cast<FC*>(rows));
  shift_spectra(rows, s_, 1.0 / m_, s, cy, offset_, window_rows_backward_, stamp_rows);
  emit(window(grid), m_, 1, out);
}

template <class Real>
template <class Shift>
void BasicMetacalImager<Real>::ramp_rows(int n, Shift shift) {
  auto* rows = static_cast<Complex*>(rows_spectrum_.data());
  Complex* group[kRotateRows];
  std::complex<double> steps[kRotateRows];
  for (int r0 = 0; r0 < n; r0 += kRotateRows) {
    const int count = std::min(kRotateRows, n - r0);
    for (int k = 0; k < count; ++k) {
      group[k] = rows + static_cast<std::size_t>(r0 + k) * h_count_;
      steps[k] = std::polar(1.0, 2 * std::numbers::pi * shift(r0 + k) / m_);
    }
    rotate_rows(group, steps, count, 1.0, h_count_);
  }
}

template <class Real>
void BasicMetacalImager<Real>::general(const std::array<double, 4>& b, double cx, double cy, double* out) {
  // B = L D X with L = [[1, 0], [l, 1]], D = diag(d1, d2), X = [[1, u / d1], [0, 1]]:
  // H(c + B (x - c)) = F(c + D X (x - c)) with F(x, y) = H(x, y + l (x - cx)), i.e.
  //   G(x, y) = F(x, cy + d2 (y - cy))                     (every column: shift, then stretch)
  //   out(x, y) = G(cx + d1 (x - cx) + u (y - cy), y)      (the stamp's rows: shift, then stretch)
  using F = Fftw<Real>;
  const double d1 = b[0], u = b[1], l = b[2] / b[0], d2 = b[3] - l * b[1];
  auto* rows = reinterpret_cast<Real*>(rows_spectrum_.data());
  auto* frows = reinterpret_cast<typename F::Complex*>(rows);
  auto* grid = static_cast<Real*>(grid_.data());
  auto* transposed = static_cast<Real*>(transposed_.data());
  const int two_h = 2 * h_count_;
  auto centred = [&](int i, double c) {  // periodic coordinate about c, in [-M/2, M/2)
    double d = i - c;
    if (d >= 0.5 * m_) d -= m_;
    if (d < -0.5 * m_) d += m_;
    return d;
  };
  // Columns (as rows of the transpose): column x read at y + l (x - cx), at the stretched rows of
  // the stamp alone (the second pass reads no other row of G).
  transpose(static_cast<const Real*>(h_.data()), m_, transposed, m_, m_, m_);
  F::execute_r2c(rows_forward_, transposed, frows);
  ramp_rows(m_, [&](int x) { return l * centred(x, cx); });
  for (int j = 0; j < s_; ++j) positions_[j] = cy + d2 * centred(offset_ + j, cy);
  Eigen::Map<RowMatrix<Real>>(grid, m_, s_).noalias() =
      Eigen::Map<const RowMatrix<Real>>(rows, m_, two_h) * Eigen::Map<const RowMatrix<Real>>(weights_for(positions_), two_h, s_);
  transpose(grid, s_, transposed, m_, m_, s_);  // G at the stamp's rows y, each a row of M
  // The stamp's rows: row y read at x + u (y - cy), at the stretched columns.
  F::execute_r2c(stamp_rows_forward_, transposed, frows);
  ramp_rows(s_, [&](int i) { return u * centred(offset_ + i, cy); });
  for (int j = 0; j < s_; ++j) positions_[j] = cx + d1 * centred(offset_ + j, cx);
  const auto product =
      Eigen::Map<const RowMatrix<Real>>(rows, s_, two_h) * Eigen::Map<const RowMatrix<Real>>(weights_for(positions_), two_h, s_);
  if constexpr (std::is_same_v<Real, double>) {
    if (!add_rotated_back_) {
      Eigen::Map<RowMatrix<Real>>(out, s_, s_).noalias() = product;
      return;
    }
  }
  Eigen::Map<RowMatrix<Real>>(scratch_t_.data(), s_, s_).noalias() = product;
  emit(scratch_t_.data(), s_, 1, out);
}

template class BasicMetacalImager<double>;
template class BasicMetacalImager<float>;

}  // namespace stampede
