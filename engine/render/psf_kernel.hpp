// The upsampled renderer's PSF kernel, built once per PSF model.
//
// The kernel is the PSF at model (sub-pixel) resolution times the sub-pixel top-hat (paper
// appendix A, "Fourier sampling kernel"), as an r2c half-spectrum on the model grid, with FFTW's
// 1/n^2 folded in. It is immutable once built and shared read-only by every thread.
#pragma once

#include <complex>
#include <memory>
#include <string>
#include <vector>

#include "engine/model/psf_model.hpp"
#include "engine/render/fft_plans.hpp"
#include "engine/render/render_options.hpp"
#include "engine/render/renderer.hpp"

namespace stampede {

class PsfKernel final : public PreparedPsf {
 public:
  // Null, with *error set, when the PSF cannot be normalised (zero, negative or non-finite flux).
  static std::shared_ptr<const PsfKernel> build(const PsfModel& psf, const GridGeometry& geometry,
                                                FftPlanCache& plans, std::string* error);

  const GridGeometry& geometry() const { return geometry_; }
  const std::complex<double>* spectrum() const { return spectrum_.data(); }
  // The spectrum folded with the block average to data resolution (FourierDownsampler::fold_kernel).
  const std::complex<double>* folded_spectrum() const { return folded_.data(); }
  // Flux of the PSF captured by the model grid (analytic PSFs are normalised on the infinite plane).
  double grid_flux() const { return grid_flux_; }
  // Adaptive second moments of the pixel-convolved PSF, pixels^2 (starting-point size correction).
  double xx() const override { return xx_; }
  double xy() const override { return xy_; }
  double yy() const override { return yy_; }

 private:
  explicit PsfKernel(const GridGeometry& g) : geometry_(g) {}
  void set_adaptive_moments(const double* wrapped, int n, double step);
  GridGeometry geometry_;
  std::vector<std::complex<double>> spectrum_;
  std::vector<std::complex<double>> folded_;
  double grid_flux_ = 0, xx_ = 0, xy_ = 0, yy_ = 0;
};

}  // namespace stampede
