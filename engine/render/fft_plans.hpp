// FFTW-backed circular convolution on an n x n real grid, planned once and executed many times.
//
// Layout: real images are n x n row-major (x fastest, the FFTW "last dimension"); spectra are the
// r2c half-spectrum of n rows x (n/2 + 1) columns. Plans are made at construction under a
// process-wide planner lock (FFTW's planner is not thread-safe, its execute functions are), and
// executed with the new-array interface on any buffer from `AlignedBuffer` (engine/common/fftw_support.hpp), so one convolver
// serves every image of its shape on its thread.
#pragma once

#include <complex>
#include <cstddef>
#include <map>
#include <memory>

#include "engine/common/fftw_support.hpp"

namespace stampede {

enum class FftPlanning { kEstimate, kMeasure };

class FftConvolver {
 public:
  FftConvolver(int n, FftPlanning planning);
  ~FftConvolver();
  FftConvolver(const FftConvolver&) = delete;
  FftConvolver& operator=(const FftConvolver&) = delete;

  int size() const { return n_; }
  std::size_t spectrum_size() const { return static_cast<std::size_t>(n_) * (n_ / 2 + 1); }

  // A fresh n x n real buffer suitable for the plans.
  AlignedBuffer make_real_buffer() const;

  // spectrum (n x (n/2+1)) = DFT(image); image is preserved.
  void forward(const double* image, std::complex<double>* spectrum);
  // The spectrum of image in this convolver's scratch buffer (valid until the next call). The
  // image is used as scratch (FFTW_DESTROY_INPUT: no internal copy of the input).
  const std::complex<double>* transform(double* image);
  // image = irfft(rfft(image) .* kernel); kernel already carries FFTW's 1/n^2.
  void convolve(double* image, const std::complex<double>* kernel);

 private:
  int n_;
  void* forward_plan_ = nullptr;   // fftw_plan
  void* backward_plan_ = nullptr;  // fftw_plan
  void* destroying_plan_ = nullptr;  // fftw_plan: r2c that may overwrite its input
  AlignedBuffer scratch_spectrum_;
  AlignedBuffer scratch_real_;
};

// Per-thread set of convolvers, one per grid size met, each planned once.
class FftPlanCache {
 public:
  explicit FftPlanCache(FftPlanning planning = FftPlanning::kMeasure) : planning_(planning) {}
  FftConvolver& get(int n);

 private:
  FftPlanning planning_;
  std::map<int, std::unique_ptr<FftConvolver>> convolvers_;
};

}  // namespace stampede
