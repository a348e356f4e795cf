// FFTW convolution; see fft_plans.hpp.
#include "engine/render/fft_plans.hpp"

#include <fftw3.h>

#include <stdexcept>

namespace stampede {

FftConvolver::FftConvolver(int n, FftPlanning planning)
    : n_(n),
      scratch_spectrum_(sizeof(fftw_complex) * static_cast<std::size_t>(n) * (n / 2 + 1)),
      scratch_real_(sizeof(double) * static_cast<std::size_t>(n) * n) {
  const unsigned flags = (planning == FftPlanning::kMeasure ? FFTW_MEASURE : FFTW_ESTIMATE) | FFTW_DESTROY_INPUT;
  auto* real = static_cast<double*>(scratch_real_.data());
  auto* spec = static_cast<fftw_complex*>(scratch_spectrum_.data());
  std::lock_guard<std::mutex> lock(fftw_planner_mutex());
  // r2c preserves its input unless told otherwise; c2r always destroys it (we own that buffer).
  forward_plan_ = fftw_plan_dft_r2c_2d(n, n, real, spec, (flags & ~FFTW_DESTROY_INPUT) | FFTW_PRESERVE_INPUT);
  backward_plan_ = fftw_plan_dft_c2r_2d(n, n, spec, real, flags);
  destroying_plan_ = fftw_plan_dft_r2c_2d(n, n, real, spec, flags);
  if (!forward_plan_ || !backward_plan_ || !destroying_plan_) throw std::runtime_error("FFTW could not plan a transform");
}

FftConvolver::~FftConvolver() {
  std::lock_guard<std::mutex> lock(fftw_planner_mutex());
  if (forward_plan_) fftw_destroy_plan(static_cast<fftw_plan>(forward_plan_));
  if (backward_plan_) fftw_destroy_plan(static_cast<fftw_plan>(backward_plan_));
  if (destroying_plan_) fftw_destroy_plan(static_cast<fftw_plan>(destroying_plan_));
}

AlignedBuffer FftConvolver::make_real_buffer() const {
  return AlignedBuffer(sizeof(double) * static_cast<std::size_t>(n_) * n_);
}

void FftConvolver::forward(const double* image, std::complex<double>* spectrum) {
  // FFTW_PRESERVE_INPUT makes the const_cast safe; new-array execution needs the plan's alignment.
  fftw_execute_dft_r2c(static_cast<fftw_plan>(forward_plan_), const_cast<double*>(image),
                       reinterpret_cast<fftw_complex*>(spectrum));
}

const std::complex<double>* FftConvolver::transform(double* image) {
  auto* spec = static_cast<std::complex<double>*>(scratch_spectrum_.data());
  fftw_execute_dft_r2c(static_cast<fftw_plan>(destroying_plan_), image, reinterpret_cast<fftw_complex*>(spec));
  return spec;
}

void FftConvolver::convolve(double* image, const std::complex<double>* kernel) {
  auto* spec = static_cast<std::complex<double>*>(scratch_spectrum_.data());
  fftw_execute_dft_r2c(static_cast<fftw_plan>(forward_plan_), image, reinterpret_cast<fftw_complex*>(spec));
  const std::size_t m = spectrum_size();
  for (std::size_t k = 0; k < m; ++k) spec[k] *= kernel[k];
  fftw_execute_dft_c2r(static_cast<fftw_plan>(backward_plan_), reinterpret_cast<fftw_complex*>(spec), image);
}

FftConvolver& FftPlanCache::get(int n) {
  auto it = convolvers_.find(n);
  if (it == convolvers_.end()) it = convolvers_.emplace(n, std::make_unique<FftConvolver>(n, planning_)).first;
  return *it->second;
}

}  // namespace stampede
