// Fits one galaxy jointly to its cutouts in several bands, as DES Y3/Y6 combine r, i, z
// (measurements in docs/multiband.md): one shape for all bands — (u0, v0), e1, e2 and the radius
// on the sky — and, per band, a bulge and a disc amplitude, so each band has its own flux and
// bulge fraction (a colour gradient in the co-elliptical bulge + disc model). Each cutout keeps its
// PSF, WCS frame, weights and flux scale, as in MultiEpochFitter:
//   chi2 = sum over bands b, cutouts c of b, pixels i of w_ci (d_ci - s_c M(shape, A_b)_ci)^2.
// The parameter vector is the free shape parameters followed by each band's free amplitudes; the
// Jacobian is the renderer's analytic one, its shape columns summed over bands and its amplitude
// columns placed in their band's slots. Bands without usable cutouts are left out of the fit
// (their fluxes NaN). An object seen in one band only is fitted by MultiEpochFitter, so a one-band
// run gives the single-tile rows bit for bit.
#pragma once

#include <span>
#include <vector>

#include "engine/fit/multi_band_result.hpp"
#include "engine/fit/multi_epoch_fitter.hpp"

namespace stampede {

class ProjectedJointProblem;

class MultiBandFitter {
 public:
  // options.renderer must be kExact (as MultiEpochFitter's).
  explicit MultiBandFitter(const FitterOptions& options);
  ~MultiBandFitter();

  // The renderer for cutouts of box_size pixels, to prepare their PSFs (any band).
  Renderer& renderer_for(int box_size) { return single_.renderer_for(box_size); }

  // Fits the cutouts of `n_bands` bands (each epoch's `band` in 0..n_bands-1), starting the shape
  // from the single-stamp moments of epochs[first] and each band's amplitudes from its first
  // cutout's. Throws std::invalid_argument for a band index out of range or n_bands outside
  // 1..kMaxBands.
  MultiBandFitResult fit(std::span<const Observation> epochs, int n_bands, std::size_t first = 0);

 private:
  class Problem;
  FitterOptions options_;
  MultiEpochFitter single_;  // renderers, the moments start and the fit of an object seen in one band
  std::unique_ptr<Problem> problem_;
  // The fit with each band's amplitudes solved linearly (options.project_amplitudes).
  bool project_ = false;
  std::unique_ptr<ProjectedJointProblem> projected_;
  std::vector<int> slot_of_cutout_;
};

}  // namespace stampede
