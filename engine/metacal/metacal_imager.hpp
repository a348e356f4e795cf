// Metacalibration's image operations on one stamp: deconvolve the PSF, shear, reconvolve
// (MetacalFilters), giving the five images of kMetacalTypes. FFTW plans made once per thread.
//
// The stamp is zero-padded to the filters' M x M grid, transformed once, and per type multiplied
// by f_T and transformed back to H_T. The image is H_T(c + A_T^-1 (x - c)) at the stamp's pixel
// centres, with c the shear centre, evaluated as the trigonometric polynomial H_T is:
//   1p, 1m (A^-1 diagonal): exactly, one axis at a time. Stamps: a dense DFT per row, then per
//     column. Stamps of 128 px or more (metadetection cells), by Bluestein's chirp-z transform
//     (ChirpResampler) straight from f_T's 2D spectrum: its columns at the stamp's stretched rows,
//     then those rows at the stretched columns, without H_T on the grid.
//   2p, 2m (A^-1 = X(s) Y(c) X(s), three one-axis shears): each a phase ramp on a row's or
//     column's 1D transform, exact for each pass; the passes' intermediate images are not band
//     limited, which costs only where H_T's spectrum reaches the Nyquist edge. For cells the first
//     pass starts from the rows' spectra (f_T's columns transformed back) and the last pass shifts
//     the stamp's rows alone.
//   any other A^-1 (the sky's shear seen through a cutout's WCS Jacobian, MetacalFilters):
//     A^-1 = L D X (L a column shear, D diagonal, X a row shear, all within the step of 1), in two
//     passes: every column shifted and stretched (a phase ramp, then a dense DFT at the stamp's
//     stretched rows), then the stamp's rows shifted and stretched likewise.
// Real: the arithmetic's precision (stamps and data are double; a cell's images may be made in
// float, within ~2e-7 of their peak, in half the time). Inputs and outputs are double either way; filters,
// chirps and phases are computed in double and rounded to Real. Allocates at construction only.
#pragma once

#include <array>
#include <complex>
#include <memory>
#include <span>
#include <vector>

#include "engine/common/fftw_support.hpp"
#include "engine/metacal/chirp_resampler.hpp"
#include "engine/metacal/metacal_filters.hpp"
#include "engine/render/fft_plans.hpp"

namespace stampede {

template <class Real>
class BasicMetacalImager {
 public:
  using Complex = std::complex<Real>;
  // The smallest FFT-friendly even period >= 2 * stamp_size (the padding keeps the deconvolved
  // light from wrapping onto the stamp).
  static int padded_size(int stamp_size);
  // The smallest FFT-friendly even period >= stamp_size + 2 margin: a whole image (a metadetection
  // cell) whose edge pixels are not measured needs only the filters' reach between its light and
  // its wrapped copy, not a second image's width.
  static int padded_size(int stamp_size, int margin);

  BasicMetacalImager(int stamp_size, int period, FftPlanning planning);
  ~BasicMetacalImager();
  BasicMetacalImager(const BasicMetacalImager&) = delete;
  BasicMetacalImager& operator=(const BasicMetacalImager&) = delete;

  int stamp_size() const { return s_; }
  int period() const { return m_; }
  // stamp: S x S row-major. out: kNumMetacalTypes images of S x S, in kMetacalTypes order.
  // (centre_x, centre_y): the shear centre in the stamp's 0-based pixel coordinates.
  // filters.period() must equal period(). turned (when not empty; S x S): fixnoise's noise field
  // turned by 90 degrees counter-clockwise about the stamp's centre; its images are turned back and
  // added to the stamp's.
  void make_images(std::span<const double> stamp, const MetacalFilters& filters, double centre_x, double centre_y,
                   std::span<double> out, std::span<const double> turned = {});

 private:
  // The image of type t from a stamp's spectrum into img (emit()'s way).
  void image(const Complex* spectrum, const MetacalFilters& filters, MetacalType t, double cx, double cy, double* img);
  // work_spectrum_ = spectrum .* filters' f_T (in Real).
  void filter_spectrum(const Complex* spectrum, const MetacalFilters& filters, MetacalType t);
  // H = irfft(spectrum .* f_T) into h_ (M x M).
  void filtered(const Complex* spectrum, const MetacalFilters& filters, MetacalType t);
  // dest[k][q] = phase steps[k]^q for q < n, k < count <= kRotateRows (the powers in double).
  static constexpr int kRotateRows = 4;
  void fill_phases(Complex* const* dest, const std::complex<double>* steps, int count, double phase, int n);
  // rows[k][q] *= phase steps[k]^q for q < n, k < count <= kRotateRows.
  void rotate_rows(Complex* const* rows, const std::complex<double>* steps, int count, double phase, int n);
  // The factors that shift n half-spectrum rows, row r by t(r) = coef x (the periodic coordinate of
  // padded index first + r about centre), scaled by `scale`: row r's q-th is scale e^{2 pi i q t / M}
  // below M/2 and scale cos(pi t) at M/2 (a real row's Nyquist term at integer x). Cached: a grid's
  // stamps, a cell's data and fixnoise images and a shear's first and last passes share them.
  const Complex* shift_table(double coef, double centre, int first, int n, double scale);
  // The first n rows of `spectra` (half spectra, M/2 + 1 each) times shift_table(coef, centre,
  // first, n, scale), transformed back into n rows of M at `grid` by `backward` (a c2r plan of n
  // rows).
  void shift_spectra(Complex* spectra, int n, double scale, double coef, double centre, int first, void* backward,
                     Real* grid);
  // Rows of `grid` (M x M), in place: row r read at x + coef x (r's periodic coordinate about
  // centre).
  void shift_rows(Real* grid, double coef, double centre);
  // out[c * out_stride + r] = in[r * in_stride + c] for r < rows, c < cols.
  static void transpose(const Real* in, int in_stride, Real* out, int out_stride, int rows, int cols);
  // The stamp's pixel (0, 0) in an M x M grid.
  const Real* window(const Real* grid) const { return grid + static_cast<std::size_t>(offset_) * m_ + offset_; }
  // An image v(y, x) = src[y row_stride + x column_stride] (y, x < S) into out (S x S): stored, or
  // turned back by 90 degrees and added (add_rotated_back_: out(y, x) += v(x, S - 1 - y)).
  void emit(const Real* src, int row_stride, int column_stride, double* out) const;
  // The 1p/1m images: H at (c + b0 (x - c), c + b1 (y - c)).
  void scaled(double b0, double b1, double cx, double cy, double* out);
  // The same for cells, from work_spectrum_ (the filtered spectrum) by two Bluestein passes.
  void scaled_from_spectrum(double b0, double b1, double cx, double cy, double* out);
  // The 2p/2m images: H at c + [[a, b], [b, a]] (x - c), from h_ (stamps) or from work_spectrum_
  // (cells).
  void sheared(double a, double b, double cx, double cy, double* out);
  // H at c + B (x - c) for any B of unit determinant.
  void general(const std::array<double, 4>& b, double cx, double cy, double* out);
  // rows_spectrum_'s first n rows (M/2 + 1 coefficients each) times exp(2 pi i q t(r) / M): each
  // row's function then reads at x + t(r).
  template <class Shift>
  void ramp_rows(int n, Shift shift);
  // Interpolation weights (2 (M/2 + 1) x n, row-major): rows 2q, 2q + 1 hold w_q cos and -w_q sin
  // of 2 pi q p_j / M for the positions p_j (padded-grid coordinates), so Re(F . e) is one product.
  void dft_weights(std::span<const double> positions, std::vector<Real>* w);
  // dft_weights at these positions, from the cache when the same positions came before: a grid's
  // stamps share their filters and centre, so every stamp's and its fixnoise's weights are the
  // first stamp's; a cutout's fixnoise pass reuses its data pass's.
  const Real* weights_for(std::span<const double> positions);

  int s_, m_, h_count_;
  int offset_;  // the stamp's pixel (0, 0) sits at padded index (offset_, offset_)
  AlignedBuffer padded_, spectrum_, work_spectrum_, h_, grid_, transposed_, rows_spectrum_;
  AlignedBuffer turned_spectrum_;  // the turned stamp's (fixnoise's)
  void* forward_2d_ = nullptr;
  void* backward_2d_ = nullptr;
  void* rows_forward_ = nullptr;   // M rows of M, r2c
  void* stamp_rows_forward_ = nullptr;  // S rows of M, r2c
  void* rows_backward_ = nullptr;  // M rows of M, c2r
  // Cells only: the filtered spectrum's columns transformed back in place (c2c), and the stamp's
  // rows of grid_ (from padded row offset_) to and from rows_spectrum_.
  void* columns_backward_ = nullptr;
  void* window_rows_forward_ = nullptr;
  void* window_rows_backward_ = nullptr;
  struct CachedWeights {
    std::vector<double> positions;
    std::vector<Real> weights;
    unsigned long long used = 0;  // clock_ at the last use; the least recent is replaced
  };
  static constexpr int kWeightSlots = 16;  // a call uses eight (two per sheared type): two calls' worth
  std::vector<CachedWeights> weight_cache_;
  unsigned long long clock_ = 0;
  std::vector<double> positions_;
  std::vector<Real> scratch_, scratch_t_;
  std::vector<std::complex<double>> phasors_;  // dft_weights' scratch
  std::vector<Complex> phases_;                // rotate_rows' powers of the steps
  struct ShiftTable {
    double coef = 0, centre = 0, scale = 0;
    int first = 0, n = 0;
    std::vector<Complex> factors;
    unsigned long long used = 0;
  };
  static constexpr int kShiftSlots = 8;  // a cell's two shears use six, a stamp's four
  std::vector<ShiftTable> shift_tables_;
  // Stamps of kChirpMinStamp pixels or more (metadetection cells) stretch by Bluestein's transform:
  // the dense sums cost O(M S) per row, this O(M log M); smaller stamps keep the dense sums, whose
  // rows (metacal's fits) are unchanged by it.
  static constexpr int kChirpMinStamp = 128;
  std::unique_ptr<BasicChirpResampler<Real>> chirp_;
  bool add_rotated_back_ = false;  // the image being made is the turned stamp's, for emit()
};

using MetacalImager = BasicMetacalImager<double>;

}  // namespace stampede
