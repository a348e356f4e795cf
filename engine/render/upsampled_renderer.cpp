// The upsampled (paper) renderer; see upsampled_renderer.hpp.
#include "engine/render/upsampled_renderer.hpp"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <tuple>
#include <stdexcept>
#include <string>

namespace stampede {

UpsampledRenderer::UpsampledRenderer(const RenderOptions& options, const ModelOptions& model,
                                     std::shared_ptr<const PsfKernel> psf, FftPlanCache& plans)
    : options_(options),
      geometry_(options),
      model_(model, geometry_.step()),
      plans_(plans),
      fft_(plans.get(geometry_.grid_size())),
      profile_kernels_(&kernels::profile_kernels(options.simd)),
      downsampler_(geometry_, options.simd) {
  if (psf) set_psf(std::move(psf));
  for (auto& g : grid_images_) g = fft_.make_real_buffer();
  const std::size_t npix = static_cast<std::size_t>(geometry_.stamp_size) * geometry_.stamp_size;
  for (auto& s : stamp_images_) s.assign(npix, 0.0);
}

std::shared_ptr<const PreparedPsf> UpsampledRenderer::prepare_psf(const PsfModel& psf, std::string* error) {
  return PsfKernel::build(psf, geometry_, plans_, error);
}

void UpsampledRenderer::set_psf(std::shared_ptr<const PreparedPsf> psf) {
  const auto* kernel = dynamic_cast<const PsfKernel*>(psf.get());
  if (!kernel) throw std::invalid_argument("UpsampledRenderer: the PSF was not prepared by an upsampled renderer");
  if (!(kernel->geometry() == geometry_)) throw std::invalid_argument("PSF kernel built for another model grid");
  kernel_ = kernel;
  psf_ = std::move(psf);
}

bool UpsampledRenderer::effective_params(const ParamVector& p, ParamVector* out) const {
  return model_.effective_params(p, out);
}

void UpsampledRenderer::component_fluxes(const ParamVector& p, double* bulge, double* disc) const {
  model_.fluxes(p, bulge, disc);
}

int UpsampledRenderer::image_of(Param p) {
  switch (p) {
    case Param::kX0: return kShapeImage + kernels::kDx0;
    case Param::kY0: return kShapeImage + kernels::kDy0;
    case Param::kE1: return kShapeImage + kernels::kDe1;
    case Param::kE2: return kShapeImage + kernels::kDe2;
    case Param::kRadius: return kShapeImage + kernels::kDr;
    case Param::kBulgeA: return kBulgeImage;
    case Param::kDiscA: return kDiscImage;
    default: return -1;
  }
}

kernels::GridRegion UpsampledRenderer::central_region(double x0, double y0) const {
  const kernels::SubpixelGrid g = geometry_.subpixel_grid();
  const int nu = options_.n_central_pixels_to_upsample;
  // Fractional sub-pixel index of the centre; the block of N_u sub-pixels nearest to it.
  auto begin = [&](double c) {
    const double idx = (c - g.origin) / g.step;
    const double b = std::floor(idx - 0.5 * (nu - 1) + 0.5);
    return static_cast<int>(std::clamp(b, 0.0, static_cast<double>(g.size)));
  };
  const int bx = begin(x0), by = begin(y0);
  return {bx, std::min(bx + nu, g.size), by, std::min(by + nu, g.size)};
}

std::array<kernels::GridRegion, 5> UpsampledRenderer::partition(double x0, double y0) const {
  const int n = geometry_.grid_size();
  kernels::GridRegion c = central_region(x0, y0);
  if (!std::isfinite(x0) || !std::isfinite(y0)) c = {0, 0, 0, 0};
  if (c.empty()) return {kernels::GridRegion{0, 0, 0, 0}, {0, n, 0, n}, {0, 0, 0, 0}, {0, 0, 0, 0}, {0, 0, 0, 0}};
  return {c,
          kernels::GridRegion{0, n, 0, c.y_begin},
          {0, n, c.y_end, n},
          {0, c.x_begin, c.y_begin, c.y_end},
          {c.x_end, n, c.y_begin, c.y_end}};
}

void UpsampledRenderer::convolve_and_downsample(double* grid_image, double* out) {
  downsampler_.apply(fft_.transform(grid_image), kernel_->folded_spectrum(), out);
}

void UpsampledRenderer::set_floor(kernels::SersicDerivativeBlock* c, int supersample, double radius) const {
  // Sample spacing h in pixels; u is (distance / r_e)^2, so the floor is h^2 / (pi r_e^2).
  const double h = geometry_.step() / supersample;
  c->shape.u_floor = h * h / (M_PI * radius * radius);
}

void UpsampledRenderer::accumulate_component(kernels::SersicDerivativeBlock* c, double radius,
                                             const std::array<kernels::GridRegion, 5>& regions, double amplitude,
                                             double* grid) {
  const kernels::SubpixelGrid g = geometry_.subpixel_grid();
  for (int r = 0; r < 5; ++r) {
    const int ss = r == 0 ? options_.n_central_pixel_upsampling : 1;
    set_floor(c, ss, radius);
    profile_kernels_->accumulate_value(g, regions[r], ss, c->shape, amplitude, grid);
  }
}

RenderStatus UpsampledRenderer::render(const ParamVector& p, std::span<double> model) {
  if (!kernel_) return RenderStatus::kNoPsf;
  ModelComponents comp;
  if (!model_.components(p, &comp)) return RenderStatus::kInvalidModel;
  const kernels::SubpixelGrid g = geometry_.subpixel_grid();
  double* grid = image(kBulgeImage);
  std::memset(grid, 0, sizeof(double) * static_cast<std::size_t>(g.size) * g.size);
  const auto regions = partition(comp.disc.shape.x0, comp.disc.shape.y0);
  for (auto [c, radius] : {std::pair{&comp.bulge, comp.bulge_radius}, std::pair{&comp.disc, comp.disc_radius}})
    if (c->amplitude != 0.0) accumulate_component(c, radius, regions, c->amplitude, grid);
  convolve_and_downsample(grid, model.data());
  return RenderStatus::kOk;
}

RenderStatus UpsampledRenderer::render_components(const ParamVector& p, std::span<double> bulge,
                                                  std::span<double> disc) {
  if (!kernel_) return RenderStatus::kNoPsf;
  ModelComponents comp;
  if (!model_.components(p, &comp)) return RenderStatus::kInvalidModel;
  const kernels::SubpixelGrid g = geometry_.subpixel_grid();
  const auto regions = partition(comp.disc.shape.x0, comp.disc.shape.y0);
  for (auto [c, radius, k, out] : {std::tuple{&comp.bulge, comp.bulge_radius, kBulgeImage, bulge.data()},
                                   std::tuple{&comp.disc, comp.disc_radius, kDiscImage, disc.data()}}) {
    double* grid = image(k);
    std::memset(grid, 0, sizeof(double) * static_cast<std::size_t>(g.size) * g.size);
    accumulate_component(c, radius, regions, 1.0, grid);
    convolve_and_downsample(grid, out);
  }
  return RenderStatus::kOk;
}

RenderStatus UpsampledRenderer::render_with_jacobian(const ParamVector& p, std::span<const Param> free,
                                                     std::span<double> model, std::span<double* const> jacobian) {
  if (!kernel_) return RenderStatus::kNoPsf;
  ModelComponents comp;
  if (!model_.components(p, &comp)) return RenderStatus::kInvalidModel;
  const kernels::SubpixelGrid g = geometry_.subpixel_grid();
  std::array<double*, kernels::kNumShapeDerivatives> deriv;
  for (int d = 0; d < kernels::kNumShapeDerivatives; ++d) deriv[d] = image(kShapeImage + d);
  const auto regions = partition(comp.disc.shape.x0, comp.disc.shape.y0);
  const int u2 = options_.n_central_pixel_upsampling;
  for (int r = 0; r < 5; ++r) {
    const int ss = r == 0 ? u2 : 1;
    set_floor(&comp.bulge, ss, comp.bulge_radius);
    set_floor(&comp.disc, ss, comp.disc_radius);
    // The regions partition the grid: the bulge's pass writes every derivative sub-pixel once (no
    // clearing needed), the disc's adds to it.
    profile_kernels_->accumulate_derivatives(g, regions[r], ss, comp.bulge, image(kBulgeImage), deriv, true);
    profile_kernels_->accumulate_derivatives(g, regions[r], ss, comp.disc, image(kDiscImage), deriv, false);
  }
  // Which convolved images are needed: the two components always (the model), shape derivatives
  // only when their parameter is free.
  std::array<bool, kNumImages> needed{};
  needed[kBulgeImage] = needed[kDiscImage] = true;
  for (Param f : free) {
    const int i = image_of(f);
    if (i < 0) throw std::invalid_argument("render_with_jacobian: parameter has no derivative image");
    needed[i] = true;
  }
  for (int k = 0; k < kNumImages; ++k)
    if (needed[k]) convolve_and_downsample(image(k), stamp_images_[k].data());
  const double ab = comp.bulge.amplitude, ad = comp.disc.amplitude;
  const auto& bulge = stamp_images_[kBulgeImage];
  const auto& disc = stamp_images_[kDiscImage];
  for (std::size_t i = 0; i < model.size(); ++i) model[i] = ab * bulge[i] + ad * disc[i];
  for (std::size_t k = 0; k < free.size(); ++k) {
    const std::vector<double>& src = stamp_images_[image_of(free[k])];
    std::copy(src.begin(), src.end(), jacobian[k]);
  }
  return RenderStatus::kOk;
}

}  // namespace stampede
