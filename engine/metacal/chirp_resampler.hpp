// Band-limited periodic rows evaluated at equally spaced positions by Bluestein's chirp-z transform:
// a row of period M given by its half spectrum F (FFTW's r2c: q = 0 .. M/2, unnormalised) is the
// trigonometric polynomial f(p) = sum_q w_q Re(F_q e^{2 pi i q p / M}) (w_q = 1/M at q = 0 and M/2,
// 2/M between), and at p_j = a + b j (j < S) the sum is a chirp-z transform:
//   f(p_j) = Re(c_j sum_q u_q v_{j-q}),  u_q = w_q F_q e^{2 pi i (q a + b q^2 / 2) / M},
//   v_k = e^{-2 pi i b k^2 / (2M)},  c_j = e^{2 pi i b j^2 / (2M)},
// a linear convolution done by FFTs of length L >= M/2 + S. The same values as the dense sum (to
// rounding) at O(L log L) per row instead of O(M S): a metadetection cell's stretched metacal
// images (MetacalImager's 1p, 1m) cost half as much this way. Allocates at construction and when a
// new (a, b) enters its cache only.
#pragma once
#include <complex>
#include <vector>

#include "engine/common/fftw_support.hpp"
#include "engine/render/fft_plans.hpp"

namespace stampede {

class ChirpResampler {
 public:
  ChirpResampler(int period, int outputs, FftPlanning planning);
  ~ChirpResampler();
  ChirpResampler(const ChirpResampler&) = delete;
  ChirpResampler& operator=(const ChirpResampler&) = delete;
  // rows: n half spectra of period() (M/2 + 1 coefficients each, consecutive); out: n rows of
  // outputs() values, row r at out + r * out_stride: f_r(a + b j).
  void resample(const std::complex<double>* rows, int n, double a, double b, double* out, int out_stride);
  int period() const { return m_; }
  int outputs() const { return s_; }

 private:
  struct Chirps {
    double a = 0, b = 0;
    std::vector<std::complex<double>> pre, kernel, post;  // u's factor (h), FFT of v (L), c_j / L (S)
    unsigned long long used = 0;
  };
  const Chirps& chirps_for(double a, double b);
  int m_, h_, s_, l_;
  AlignedBuffer work_;  // one row of L
  void* forward_ = nullptr;
  void* backward_ = nullptr;
  std::vector<Chirps> cache_;
  unsigned long long clock_ = 0;
};

}  // namespace stampede
