// Sérsic profile images on the upsampled (sub-pixel) model grid, and their analytic derivatives.
//
// Grid layout: a square grid of `size` x `size` sub-pixels stored row-major (x fastest). Sub-pixel
// (i, j) has its centre at (origin + step * i, origin + step * j) in data-pixel coordinates
// (0-based, pixel centres at integers). A sub-pixel's value is the profile's intensity (flux per
// pixel^2) at its centre, or, with `supersample` = s > 1, the mean over an s x s grid of points at
// the centres of its s x s cells (the im3shape central-region integration).
#pragma once

#include <array>
#include <cstddef>

#include "kernels/ellipse.hpp"
#include "kernels/isa.hpp"

namespace stampede::kernels {

struct SubpixelGrid {
  int size = 0;        // sub-pixels per side
  double origin = 0;   // data-pixel coordinate of sub-pixel 0's centre
  double step = 1;     // sub-pixel size in data pixels (1 / upsampling)
};

// Half-open rectangle [x_begin, x_end) x [y_begin, y_end) of sub-pixel indices.
struct GridRegion {
  int x_begin = 0, x_end = 0, y_begin = 0, y_end = 0;
  bool empty() const { return x_begin >= x_end || y_begin >= y_end; }
};

// Which root u^(1/2n) needs: chosen once per component, never inside the pixel loop.
enum class SersicRoot {
  kSquareRoot,   // n = 1 (exponential disc): sqrt(u)
  kEighthRoot,   // n = 4 (de Vaucouleurs bulge): sqrt(sqrt(sqrt(u)))
  kGeneralPow,   // any other n: pow(u, 1/2n)
};

// One component's shape, precomputed once per model evaluation:
//   value(x, y) = exp(-b * u^(1/2n)),  u = q(x - x0, y - y0) = (elliptical distance / r_e)^2.
struct SersicBlock {
  double x0 = 0, y0 = 0;
  EllipseQuadratic q;
  // Samples nearer the centre than the radius of a disc with their cell's area, h / sqrt(pi), take
  // the profile's value at that radius (close to the cell mean of the cusp; a sample on r = 0 would
  // return the central intensity, ~15x the mean for n = 4). Set per region by the renderer as
  // u_floor = h^2 / (pi r_e^2), h the sample spacing in pixels; 0 disables.
  double u_floor = 0;
  double b = 1;
  double inv_2n = 0.5;
  SersicRoot root = SersicRoot::kSquareRoot;
};

// What the derivative kernel needs beyond the shape: the component amplitude and du/d(parameter)
// coefficients already chained through the parameterisation (mirror, bulge offsets, softening).
struct SersicDerivativeBlock {
  SersicBlock shape;
  double amplitude = 0;
  EllipseQuadratic dq_de1;  // du/de1 = dq_de1(dx, dy)
  EllipseQuadratic dq_de2;  // du/de2 = dq_de2(dx, dy)
  double du_dr_over_u = 0;  // du/dr = du_dr_over_u * u (also for u_floor, which scales as 1/r^2)
};

// Indices of the shape derivative images.
enum ShapeDerivative : int { kDx0 = 0, kDy0 = 1, kDe1 = 2, kDe2 = 3, kDr = 4, kNumShapeDerivatives = 5 };

SersicRoot sersic_root_for(double n);

// Single-point evaluation (for tests and the profile invariants).
double sersic_value(const SersicBlock& block, double x, double y);

// The pixel kernels, one build per instruction set from one source (profile_render_impl.hpp):
// accumulate_value: out[j * size + i] += amplitude * value over the region (sub-pixel means when
//   supersample > 1);
// accumulate_derivatives: value[k] = unit-amplitude value (overwritten; skipped when null), and
//   derivative[p][k] += amplitude * d value / d p for the five shape parameters (with overwrite:
//   derivative[p][k] = ..., so a first pass over a partition of the grid needs no cleared images).
struct ProfileKernels {
  const char* name = "";
  int lanes = 1;  // doubles per vector
  void (*accumulate_value)(const SubpixelGrid& grid, const GridRegion& region, int supersample,
                           const SersicBlock& block, double amplitude, double* out) = nullptr;
  void (*accumulate_derivatives)(const SubpixelGrid& grid, const GridRegion& region, int supersample,
                                 const SersicDerivativeBlock& block, double* value,
                                 const std::array<double*, kNumShapeDerivatives>& derivative, bool overwrite) = nullptr;
};

// The kernels for a set; nullptr when it was not compiled in or this CPU lacks it.
const ProfileKernels* profile_kernels_for(Isa isa);
// profile_kernels_for(isa), or the scalar kernels when that set is unavailable.
const ProfileKernels& profile_kernels(Isa isa = Isa::kBest);

// Shorthands through profile_kernels().
void accumulate_sersic(const SubpixelGrid& grid, const GridRegion& region, int supersample,
                       const SersicBlock& block, double amplitude, double* out);
void accumulate_sersic_derivatives(const SubpixelGrid& grid, const GridRegion& region, int supersample,
                                   const SersicDerivativeBlock& block, double* value,
                                   const std::array<double*, kNumShapeDerivatives>& derivative);

}  // namespace stampede::kernels
