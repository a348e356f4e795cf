// The paper-faithful renderer (im3shape section 4.1 and appendices A, D): bulge and disc drawn on
// an upsampled grid (sub-pixel centres; the central N_u x N_u sub-pixels integrated on a U2 x U2
// grid), convolved with the PSF kernel by FFT, block-averaged to data resolution. Derivative
// images are drawn analytically on the same grid and go through the same convolution and
// downsampling, so the Jacobian is exact for the discretised model.
//
// One renderer per thread: it owns its scratch images; the PSF kernel is shared read-only.
#pragma once

#include <array>
#include <memory>
#include <vector>

#include "engine/render/fft_plans.hpp"
#include "engine/render/fourier_downsampler.hpp"
#include "engine/model/galaxy_model.hpp"
#include "engine/render/psf_kernel.hpp"
#include "engine/render/render_options.hpp"
#include "engine/render/renderer.hpp"

namespace stampede {

class UpsampledRenderer final : public Renderer {
 public:
  // options and psf must describe the same grid (psf->geometry() == GridGeometry(options)).
  UpsampledRenderer(const RenderOptions& options, const ModelOptions& model, std::shared_ptr<const PsfKernel> psf,
              FftPlanCache& plans);

  int stamp_size() const override { return geometry_.stamp_size; }
  RenderStatus render(const ParamVector& p, std::span<double> model) override;
  RenderStatus render_with_jacobian(const ParamVector& p, std::span<const Param> free, std::span<double> model,
                                    std::span<double* const> jacobian) override;

  const GalaxyModel& galaxy_model() const { return model_; }
  // Swaps the PSF (same grid); for per-object PSFs.
  void set_psf(std::shared_ptr<const PsfKernel> psf);
  const GridGeometry& geometry() const { return geometry_; }

  // The sub-pixel block integrated at U2 for a galaxy centred at (x0, y0) (exposed for tests).
  kernels::GridRegion central_region(double x0, double y0) const;

 private:
  // The grid cut into the central block and the four rectangles around it.
  std::array<kernels::GridRegion, 5> partition(double x0, double y0) const;
  double* image(int k) { return static_cast<double*>(grid_images_[k].data()); }
  void convolve_and_downsample(double* grid_image, double* out);
  // The cusp floor (profile_render.hpp, SersicBlock::u_floor) for samples spaced step / supersample.
  void set_floor(kernels::SersicDerivativeBlock* c, int supersample, double radius) const;

  RenderOptions options_;
  GridGeometry geometry_;
  GalaxyModel model_;
  std::shared_ptr<const PsfKernel> psf_;
  FftConvolver& fft_;
  const kernels::ProfileKernels* profile_kernels_;  // options_.simd's build
  FourierDownsampler downsampler_;
  // Grid images: 0 bulge, 1 disc, 2..6 shape derivatives (x0, y0, e1, e2, r).
  std::array<AlignedBuffer, 7> grid_images_;
  std::array<std::vector<double>, 7> stamp_images_;
};

}  // namespace stampede
