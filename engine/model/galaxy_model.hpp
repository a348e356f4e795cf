// The im3shape bulge + disc model: from a parameter vector to the two Sérsic components the
// kernels render, with the reparameterisations of the paper's appendix A:
//  - ellipticity mirrored radially about |e| = `ellipticity_mirror` (a triangle wave in |e|, so
//    the optimiser may wander anywhere and the model stays valid);
//  - disc radius softened: r -> (R + r^2 / R) / 2 for |r| < R, |r| otherwise, with R given in
//    sub-pixels (0.4), so the radius used is never below R / 2.
#pragma once

#include <string>

#include "engine/model/parameters.hpp"
#include "kernels/profile_render.hpp"

namespace stampede {

struct ModelOptions {
  double ellipticity_mirror = 0.95;  // |e| at which the ellipticity is mirrored (appendix A)
  double radius_softening = 0.4;     // transition radius R of the softening, in sub-pixels

  // Message names the option, its value and the broken constraint.
  bool IsValid(std::string* why) const;
};

// d(effective e) / d(parameter e) and the effective value, for one ellipticity.
struct EffectiveEllipticity {
  double e1 = 0, e2 = 0;
  double d[2][2] = {{1, 0}, {0, 1}};  // d[i][j] = d e_eff_i / d e_j
};

EffectiveEllipticity mirror_ellipticity(double e1, double e2, double mirror);
// Softened radius and its derivative with respect to r.
double soften_radius(double r, double transition, double* derivative);

// The two components, ready for the kernels.
struct ModelComponents {
  kernels::SersicDerivativeBlock bulge;
  kernels::SersicDerivativeBlock disc;
  double bulge_radius = 0;  // effective half-light radii, pixels
  double disc_radius = 0;
  double e1 = 0, e2 = 0;    // effective disc ellipticity
};

class GalaxyModel {
 public:
  // subpixel_step: size of a model sub-pixel in data pixels (1 / upsampling).
  GalaxyModel(const ModelOptions& options, double subpixel_step);

  // False when no valid model exists for p (non-finite values, |e_bulge| >= 1 after offsets).
  bool components(const ParamVector& p, ModelComponents* out) const;

  // p with e1, e2 and the radius replaced by the values drawn (mirrored, softened): what every
  // renderer's effective_params returns. False when no model exists for p (*out still filled).
  bool effective_params(const ParamVector& p, ParamVector* out) const;

  // Analytic total fluxes of the two components (area-preserving shear keeps them).
  void fluxes(const ParamVector& p, double* bulge_flux, double* disc_flux) const;

  const ModelOptions& options() const { return options_; }
  double softening_transition() const { return transition_; }

 private:
  ModelOptions options_;
  double transition_;  // softening transition radius in data pixels
};

}  // namespace stampede
