// Metacalibration's image operations on one stamp: deconvolve the PSF, shear, reconvolve
// (MetacalFilters), giving the five images of kMetacalTypes. FFTW plans made once per thread.
//
// The stamp is zero-padded to the filters' M x M grid, transformed once, and per type multiplied
// by f_T and transformed back to H_T. The image is H_T(c + A_T^-1 (x - c)) at the stamp's pixel
// centres, with c the shear centre, evaluated as the trigonometric polynomial H_T is:
//   1p, 1m (A^-1 diagonal): exactly, one axis at a time (a dense DFT per row, then per column; for
//     stamps of 128 px or more Bluestein's chirp-z transform, ChirpResampler);
//   2p, 2m (A^-1 = X(s) Y(c) X(s), three one-axis shears): each a phase ramp on a row's or
//     column's 1D transform, exact for each pass; the passes' intermediate images are not band
//     limited, which costs only where H_T's spectrum reaches the Nyquist edge.
//   any other A^-1 (the sky's shear seen through a cutout's WCS Jacobian, MetacalFilters):
//     A^-1 = L D X (L a column shear, D diagonal, X a row shear, all within the step of 1), in two
//     passes: every column shifted and stretched (a phase ramp, then a dense DFT at the stamp's
//     stretched rows), then the stamp's rows shifted and stretched likewise.
// Allocates at construction only.
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

class MetacalImager {
 public:
  // The smallest FFT-friendly even period >= 2 * stamp_size (the padding keeps the deconvolved
  // light from wrapping onto the stamp).
  static int padded_size(int stamp_size);
  // The smallest FFT-friendly even period >= stamp_size + 2 margin: a whole image (a metadetection
  // cell) whose edge pixels are not measured needs only the filters' reach between its light and
  // its wrapped copy, not a second image's width.
  static int padded_size(int stamp_size, int margin);

  MetacalImager(int stamp_size, int period, FftPlanning planning);
  ~MetacalImager();
  MetacalImager(const MetacalImager&) = delete;
  MetacalImager& operator=(const MetacalImager&) = delete;

  int stamp_size() const { return s_; }
  int period() const { return m_; }
  // stamp: S x S row-major. out: kNumMetacalTypes images of S x S, in kMetacalTypes order.
  // (centre_x, centre_y): the shear centre in the stamp's 0-based pixel coordinates.
  // filters.period() must equal period().
  void make_images(std::span<const double> stamp, const MetacalFilters& filters, double centre_x, double centre_y,
                   std::span<double> out);

 private:
  // H = irfft(spectrum_ .* f) into h_ (M x M).
  void filtered(const std::complex<double>* f);
  // Rows of `grid` (M x M): each row r shifted by shift(r) (its values at x + shift), in place.
  // rows[k][q] *= phase steps[k]^q for q < n, k < count <= kRotateRows.
  static constexpr int kRotateRows = 4;
  void rotate_rows(std::complex<double>* const* rows, const std::complex<double>* steps, int count,
                   std::complex<double> phase, int n);
  template <class Shift>
  void shift_rows(double* grid, Shift shift);
  void transpose(const double* in, double* out, int rows, int cols);
  // The 1p/1m images: H at (c + b0 (x - c), c + b1 (y - c)).
  void scaled(double b0, double b1, double cx, double cy, double* out);
  // The 2p/2m images: H at c + [[a, b], [b, a]] (x - c).
  void sheared(double a, double b, double cx, double cy, double* out);
  // H at c + B (x - c) for any B of unit determinant.
  void general(const std::array<double, 4>& b, double cx, double cy, double* out);
  // rows_spectrum_'s first n rows (M/2 + 1 coefficients each) times exp(2 pi i q t(r) / M): each
  // row's function then reads at x + t(r).
  template <class Shift>
  void ramp_rows(int n, Shift shift);
  // Interpolation weights (2 (M/2 + 1) x n, row-major): rows 2q, 2q + 1 hold w_q cos and -w_q sin
  // of 2 pi q p_j / M for the positions p_j (padded-grid coordinates), so Re(F . e) is one product.
  void dft_weights(std::span<const double> positions, std::vector<double>* w);
  // dft_weights at these positions, from the cache when the same positions came before: a grid's
  // stamps share their filters and centre, so every stamp's and its fixnoise's weights are the
  // first stamp's; a cutout's fixnoise pass reuses its data pass's.
  const double* weights_for(std::span<const double> positions);

  int s_, m_, h_count_;
  int offset_;  // the stamp's pixel (0, 0) sits at padded index (offset_, offset_)
  AlignedBuffer padded_, spectrum_, work_spectrum_, h_, grid_, transposed_, rows_spectrum_;
  void* forward_2d_ = nullptr;
  void* backward_2d_ = nullptr;
  void* rows_forward_ = nullptr;   // M rows of M, r2c
  void* stamp_rows_forward_ = nullptr;  // S rows of M, r2c
  void* rows_backward_ = nullptr;  // M rows of M, c2r
  struct CachedWeights {
    std::vector<double> positions, weights;
    unsigned long long used = 0;  // clock_ at the last use; the least recent is replaced
  };
  static constexpr int kWeightSlots = 16;  // a call uses eight (two per sheared type): two calls' worth
  std::vector<CachedWeights> weight_cache_;
  unsigned long long clock_ = 0;
  std::vector<double> positions_, scratch_, scratch_t_;
  std::vector<std::complex<double>> phasors_;  // dft_weights' scratch
  std::vector<std::complex<double>> phases_;   // rotate_rows' powers of the steps
  // Stamps of kChirpMinStamp pixels or more (metadetection cells) stretch by Bluestein's transform:
  // the dense sums cost O(M S) per row, this O(M log M); smaller stamps keep the dense sums, whose
  // rows (metacal's fits) are unchanged by it.
  static constexpr int kChirpMinStamp = 128;
  std::unique_ptr<ChirpResampler> chirp_;
};

}  // namespace stampede
