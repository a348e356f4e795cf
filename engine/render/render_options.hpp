// Resolution options of the model renderer (im3shape section 4.1) and the grid they imply.
#pragma once

#include <string>

#include "kernels/math/fft_size.hpp"
#include "kernels/profile_render.hpp"

namespace stampede {

struct ExactRenderOptions {
  // The exact renderer's options (renderer = exact).
  // Alias terms whose |PSF transform x pixel sinc| (PPi, with PPi(0) = 1) is at most this are
  // dropped (by blocks of 8 columns: a block is kept when any of its values exceeds it). The error
  // on the GalSim render_cases discs (no wrap to speak of at exact_period) falls with the tolerance
  // to GalSim's own floor near 1e-8, and the term count grows. Default 1e-7: its error is far
  // inside the 1e-5 budget for a few more terms than 1e-6 (docs/performance.md, "The exact
  // renderer's constants").
  double psf_tolerance = 1e-7;
  // Period N of the grid in pixels; 0: exact_period(stamp_size).
  int period = 0;
  // The copies' light subtracted: at most this many rings of copies (0: none), and Chebyshev
  // nodes per stamp axis (measured: exact_renderer_test, WrappedLight).
  int wrap_rings = 6;
  int wrap_nodes = 12;
  // The surrogate a fit iterates on before its exact iterations (Renderer::surrogate,
  // engine/fit/fitter.hpp): this renderer on a smaller period (0: exact_surrogate_period, 64 for
  // 39 pixels), a looser term tolerance and one ring of copies subtracted on coarser nodes; the
  // same model to within a small fraction of the peak at a fraction of a render's cost
  // (docs/performance.md, "The surrogate fit and `renderer = auto`"). Off: every iteration is exact.
  bool surrogate = true;
  int surrogate_period = 0;
  double surrogate_psf_tolerance = 1e-4;
  int surrogate_wrap_rings = 1;
  int surrogate_wrap_nodes = 6;

  bool IsValid(std::string* why) const;
};

struct RenderOptions {
  int stamp_size = 39;                    // data pixels per stamp side
  int upsampling = 5;                     // U1: model sub-pixels per data pixel, per side
  int n_central_pixels_to_upsample = 3;   // N_u: side of the central block of sub-pixels integrated finely
  int n_central_pixel_upsampling = 7;     // U2: integration points per sub-pixel side in that block
  // Data pixels of model grid added on every side of the stamp. Without it, light the PSF scatters
  // in from outside the stamp is missing from the model and the model's own edge wraps around the
  // FFT: a de Vaucouleurs bulge with r_e = 3.2 px in a 25 px stamp then has m = -5.5e-3 / +5.4e-3;
  // 2 px of padding give 1.4e-3, 4 px 2e-4 (noise-free ring test, README "Accuracy").
  int padding = 4;
  // Instruction set of the profile kernels: kBest picks the widest this CPU supports. Sets agree
  // to a few ulp; name one to make fits bitwise identical across machines.
  kernels::Isa simd = kernels::Isa::kBest;
  // The exact renderer's (renderer = exact; engine/render/exact_renderer.hpp).
  ExactRenderOptions exact;

  // Message names the option (as in the ini file), its value and the constraint.
  bool IsValid(std::string* why) const;
};

// The upsampled model grid: upsampling x M sub-pixels per side, M the FFT-friendly size at least
// stamp_size + 2 padding (a whole number of data pixels, so the downsampling can be done in
// Fourier space); the stamp sits in the middle (the margins may differ by one sub-pixel).
struct GridGeometry {
  int stamp_size = 0;
  int upsampling = 1;
  int padding = 0;
  int size = 0;    // sub-pixels per side
  int offset = 0;  // sub-pixel index of the stamp's first sub-pixel

  explicit GridGeometry(const RenderOptions& o)
      : stamp_size(o.stamp_size),
        upsampling(o.upsampling),
        padding(o.padding),
        size(o.upsampling * kernels::fft_friendly_size(o.stamp_size + 2 * o.padding)),
        offset((size - o.upsampling * o.stamp_size) / 2) {}
  int grid_size() const { return size; }
  double step() const { return 1.0 / upsampling; }
  // Sub-pixel i's centre is at data coordinate (i - offset + 0.5) / U1 - 0.5.
  kernels::SubpixelGrid subpixel_grid() const { return {size, (0.5 - offset) * step() - 0.5, step()}; }
  int data_offset() const { return offset; }
  bool operator==(const GridGeometry&) const = default;
};

}  // namespace stampede
