// The light that a Sérsic component's periodic copies put on the stamp: what the exact renderer
// subtracts so that its period N can be small (a few stamp widths of untruncated de Vaucouleurs
// wings otherwise wrap around; see engine/render/exact_renderer.hpp).
//
// Far from its centre a component convolved with the PSF and the pixel box is smooth on the
// blur's scale, so it is its unblurred profile times the exponential of the blur's second-order
// term (the cumulant form, exact for an exponential wing under a Gaussian blur; saturated where the
// profile is steep on the blur's scale, see blurred_wing):
//   (I * B)(x) = I(x) exp(1/2 M : grad grad I(x) / I(x)) (1 + O(|M|^2 grad^4)),
// M the second moments of PSF x pixel (finite for Moffat beta > 2, truncated Moffats; not for the
// Airy disc). The copies are at d_min >= N - stamp from every stamp pixel.
//
// The copies' light is smooth across the stamp, so it is evaluated at p x p Chebyshev nodes and
// interpolated to the pixels with two small matrix products per image.
#pragma once

#include <array>
#include <span>
#include <vector>

#include "kernels/ellipse.hpp"
#include "kernels/isa.hpp"
#include "kernels/profile_render.hpp"

namespace stampede::kernels {

// Second moments of the blur (PSF x pixel box), pixels^2.
struct BlurMoments {
  double xx = 0, xy = 0, yy = 0;
};

// One component at unit amplitude, value exp(-b u^s), u = q(x - x0, y - y0), s = 1 / (2 n), with
// the derivative forms the fitter's parameterisation gives (kernels/profile_render.hpp's
// SersicDerivativeBlock).
struct WingComponent {
  double x0 = 0, y0 = 0;
  EllipseQuadratic q;
  double b = 1, s = 0.5;
  SersicRoot root = SersicRoot::kSquareRoot;  // how u^s is taken (s = 1/2, 1/8 without pow)
  EllipseQuadratic dq_de1, dq_de2;
  double du_dr_over_u = 0;
};

// The five shape derivatives, in the order of kernels/profile_render.hpp's ShapeDerivative.
inline constexpr int kWingDerivatives = 5;  // x0, y0, e1, e2, radius

// The offset of one periodic copy, (i N, j N).
struct CopyOffset {
  double dx = 0, dy = 0;
};

// The copies of `c` (rings 0 < max(|i|, |j|) <= max_rings, outwards until a ring adds none) whose
// blurred value anywhere on the stamp [0, size - 1]^2 can exceed `floor`: a bound from the nearest
// stamp point, the ellipse's smallest axis and the saturated blur's largest factor (e^sqrt(6)), so
// the copies left out are each below it.
// `out` is cleared, then filled (reserve (2 max_rings + 1)^2 to keep this allocation-free).
void significant_copies(const WingComponent& c, int period, int size, int max_rings, double floor,
                        std::vector<CopyOffset>* out);

// The kernels, one build per instruction set from one source (wrapped_wings_impl.hpp):
// add_wings: for points j < count, value[j] += value_scale * W(x[j], y[j]) (value null: skipped)
// and, with derivative non-null, derivative[k][j] += derivative_scale * dW/dp_k for the five shape
// parameters, W the light of the copies at c's centre + copies[i], blurred to second order (the
// cumulant form, saturated; see the implementation).
struct WrapKernels {
  const char* name = "";
  int lanes = 1;
  void (*add_wings)(const WingComponent& c, const BlurMoments& m, const CopyOffset* copies, int ncopies,
                    const double* x, const double* y, int count, double value_scale, double* value,
                    double derivative_scale, double* const* derivative) = nullptr;
  // ChebyshevStamp::add_interpolated's two matrix products.
  void (*interpolate)(int size, int nodes, const double* basis, const double* basis_t, const double* values,
                      double* out, double* scratch) = nullptr;
};
// The kernels for a set; nullptr when it was not compiled in or this CPU lacks it.
const WrapKernels* wrap_kernels_for(Isa isa);
// wrap_kernels_for(isa), or the scalar kernels when that set is unavailable.
const WrapKernels& wrap_kernels(Isa isa = Isa::kBest);

// Scalar conveniences over the scalar kernels: the blurred far-field value of one component
// centred at (x0, y0) at point (x, y), and of the copies at c's centre + offset summed there, with
// their five derivatives (null: value only).
double blurred_wing(const WingComponent& c, const BlurMoments& m, double x, double y,
                    std::array<double, kWingDerivatives>* derivatives);
double wrapped_wings(const WingComponent& c, const BlurMoments& m, std::span<const CopyOffset> copies, double x,
                     double y, std::array<double, kWingDerivatives>* derivatives);

// Interpolation of a smooth function on the stamp's pixel centres 0 .. size - 1 (both axes) from
// its values at nodes x nodes Chebyshev points spanning them.
class ChebyshevStamp {
 public:
  ChebyshevStamp() = default;
  // isa: the set add_interpolated runs on.
  ChebyshevStamp(int size, int nodes, Isa isa = Isa::kBest);
  int size() const { return size_; }
  int nodes() const { return nodes_; }
  // Node coordinate j (pixels), the same on both axes.
  double node(int j) const { return node_[static_cast<std::size_t>(j)]; }
  // out[y * size + x] += interpolant at pixel (x, y) of values[jy * nodes + jx]; scratch holds
  // nodes * size doubles.
  void add_interpolated(const double* values, double* out, double* scratch) const;

 private:
  int size_ = 0, nodes_ = 0;
  std::vector<double> node_;
  std::vector<double> basis_;    // basis_[x * nodes + j] = Lagrange basis j at pixel x
  std::vector<double> basis_t_;  // basis_t_[j * size + x], the same transposed
  const WrapKernels* kernels_ = nullptr;
};

}  // namespace stampede::kernels
