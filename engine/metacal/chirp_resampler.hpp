// Band-limited periodic functions evaluated at equally spaced positions by Bluestein's chirp-z
// transform, in two forms:
//  - resample(): real rows of period M given by their half spectra F (FFTW's r2c: q = 0 .. M/2,
//    unnormalised): f(p) = sum_q w_q Re(F_q e^{2 pi i q p / M}) (w_q = 1/M at q = 0 and M/2, 2/M
//    between);
//  - resample_columns(): complex columns of M full-spectrum coefficients F_k (k = 0 .. M-1, k >= M/2
//    standing for k - M), such as the columns of a 2D r2c spectrum: g(p) = sum_k W_k F_k
//    e^{2 pi i k p / M} over k = -M/2 .. M/2, the Nyquist coefficient split in halves between +-M/2
//    (W = M/2 there, M elsewhere), so that at integer p g is M times FFTW's backward c2c of the column
//    and its values are the half spectra resample() reads of the rows of the real 2D function.
// At p_j = a + b j (j < S) each sum is a chirp-z transform,
//   sum_k u_k e^{2 pi i k b j / M} = c_j sum_k u_k e^{i pi b k^2 / M} e^{-i pi b (j-k)^2 / M},
// a linear convolution done by FFTs of length L >= (coefficients) + S: the same values as the dense
// sum (to rounding) at O(L log L) per row instead of O(M S). The chirps are computed in double and
// rounded to Real. Allocates at construction and when a new (a, b) enters its cache only.
#pragma once
#include <complex>
#include <vector>

#include "engine/common/fftw_support.hpp"
#include "engine/render/fft_plans.hpp"

namespace stampede {

template <class Real>
class BasicChirpResampler {
 public:
  using Complex = std::complex<Real>;
  BasicChirpResampler(int period, int outputs, FftPlanning planning);
  ~BasicChirpResampler();
  BasicChirpResampler(const BasicChirpResampler&) = delete;
  BasicChirpResampler& operator=(const BasicChirpResampler&) = delete;
  // rows: n half spectra of period() (M/2 + 1 coefficients each, consecutive); out: n rows of
  // outputs() values, row r at out + r * out_stride: f_r(a + b j).
  void resample(const Complex* rows, int n, double a, double b, Real* out, int out_stride);
  // columns: n columns of M coefficients, column c's k-th at columns[k * stride + c]; out: column
  // c's g_c(a + b j) at out[j * out_stride + c] (j < outputs()).
  void resample_columns(const Complex* columns, int n, int stride, double a, double b, Complex* out, int out_stride);
  int period() const { return m_; }
  int outputs() const { return s_; }

 private:
  struct Chirps {
    bool columns = false;
    double a = 0, b = 0;
    std::vector<Complex> pre, kernel, post;  // u's factor, FFT of the chirp kernel (L), c_j / L (S)
    unsigned long long used = 0;
  };
  const Chirps& chirps_for(bool columns, double a, double b);
  int m_, h_, s_, l_rows_, l_columns_;
  AlignedBuffer rows_work_, columns_work_;
  void* rows_forward_ = nullptr;
  void* rows_backward_ = nullptr;
  void* columns_forward_ = nullptr;
  void* columns_backward_ = nullptr;
  std::vector<Chirps> cache_;
  unsigned long long clock_ = 0;
};

using ChirpResampler = BasicChirpResampler<double>;

}  // namespace stampede
