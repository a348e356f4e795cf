// The paper-faithful renderer (im3shape section 4.1 and appendices A, D): bulge and disc drawn on
// an upsampled grid (sub-pixel centres; the central N_u x N_u sub-pixels integrated on a U2 x U2
// grid), convolved with the PSF kernel by FFT, block-averaged to data resolution. Derivative
// images are drawn analytically on the same grid and go through the same convolution and
// downsampling, so the Jacobian is exact for the discretised model.
//
// One renderer per thread: it owns its scratch images; the PSF kernel (render/psf_kernel, its
// PreparedPsf) is shared read-only.
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
  // psf may be null (set_psf before rendering); otherwise it must be built for this grid
  // (psf->geometry() == GridGeometry(options)). `plans` must outlive the renderer.
  UpsampledRenderer(const RenderOptions& options, const ModelOptions& model, std::shared_ptr<const PsfKernel> psf,
                    FftPlanCache& plans);

  int stamp_size() const override { return geometry_.stamp_size; }
  // A PsfKernel on this renderer's grid, with this thread's plans.
  std::shared_ptr<const PreparedPsf> prepare_psf(const PsfModel& psf, std::string* error) override;
  void set_psf(std::shared_ptr<const PreparedPsf> psf) override;
  RenderStatus render(const ParamVector& p, std::span<double> model) override;
  RenderStatus render_with_jacobian(const ParamVector& p, std::span<const Param> free, std::span<double> model,
                                    std::span<double* const> jacobian) override;
  RenderStatus render_components(const ParamVector& p, std::span<double> bulge, std::span<double> disc) override;
  bool effective_params(const ParamVector& p, ParamVector* out) const override;
  void component_fluxes(const ParamVector& p, double* bulge, double* disc) const override;

  const GridGeometry& geometry() const { return geometry_; }

 private:
  // The sub-pixel block integrated at U2 for a galaxy centred at (x0, y0).
  kernels::GridRegion central_region(double x0, double y0) const;
  // The grid cut into the central block and the four rectangles around it.
  std::array<kernels::GridRegion, 5> partition(double x0, double y0) const;
  double* image(int k) { return static_cast<double*>(grid_images_[k].data()); }
  void convolve_and_downsample(double* grid_image, double* out);
  // Adds one component's values at `amplitude` to the sub-pixel grid, region by region.
  void accumulate_component(kernels::SersicDerivativeBlock* c, double radius,
                            const std::array<kernels::GridRegion, 5>& regions, double amplitude, double* grid);
  // The cusp floor (profile_render.hpp, SersicBlock::u_floor) for samples spaced step / supersample.
  void set_floor(kernels::SersicDerivativeBlock* c, int supersample, double radius) const;
  // The image whose convolution is d model / d p (an amplitude's is its component's unit image);
  // -1 when p has none.
  static int image_of(Param p);

  RenderOptions options_;
  GridGeometry geometry_;
  GalaxyModel model_;
  std::shared_ptr<const PreparedPsf> psf_;  // holds kernel_
  const PsfKernel* kernel_ = nullptr;
  FftPlanCache& plans_;
  FftConvolver& fft_;
  const kernels::ProfileKernels* profile_kernels_;  // options_.simd's build
  FourierDownsampler downsampler_;
  // Grid images: kBulgeImage, kDiscImage, then the shape derivatives from kShapeImage on in
  // kernels::ShapeDerivative order (x0, y0, e1, e2, r).
  static constexpr int kBulgeImage = 0, kDiscImage = 1, kShapeImage = 2;
  static constexpr int kNumImages = kShapeImage + kernels::kNumShapeDerivatives;
  std::array<AlignedBuffer, kNumImages> grid_images_;
  std::array<std::vector<double>, kNumImages> stamp_images_;
};

}  // namespace stampede
