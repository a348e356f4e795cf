// Fits one galaxy jointly to all its cutouts (the paper's extension (i); DES Y1's im3shape): the
// model lives on the sky's tangent plane (u, v) in arcsec, and each cutout sees it through its own
// WCS Jacobian (model/pixel_frame), PSF, weights and flux scale:
//   chi2 = sum over cutouts c, pixels i of w_ci (d_ci - s_c M_c(p)_i)^2,
// its normal equations summed likewise. Levenberg-Marquardt over every free parameter jointly
// (x0, y0 are u0, v0; the radius is in arcsec; amplitudes per arcsec^2), drawn by the exact
// renderer, which carries the frames exactly (render/exact_renderer). One fitter per thread;
// renderers are made per cutout size on first use and kept, so a run allocates only as new box
// sizes appear.
#pragma once

#include <map>
#include <memory>
#include <span>
#include <vector>

#include "engine/fit/fit_result.hpp"
#include "engine/fit/fitter.hpp"
#include "engine/fit/observation.hpp"
#include "engine/model/pixel_frame.hpp"
#include "engine/render/exact_renderer.hpp"

namespace stampede {

class ProjectedJointProblem;

class MultiEpochFitter {
 public:
  // options.renderer must be kExact; options.render.stamp_size is not used (each cutout's is).
  MultiEpochFitter(const FitterOptions& options);
  ~MultiEpochFitter();

  // The renderer for cutouts of box_size pixels (made on first use), e.g. to prepare their PSFs.
  Renderer& renderer_for(int box_size);

  // Fits from `start` (sky units). Result: params, errors and fluxes in sky units; chi2 and S/N
  // summed over the cutouts; n_pixels the unmasked pixels of all of them.
  FitResult fit(std::span<const Observation> epochs, const ParamVector& start);
  // Fits from joint_start(epochs, first); *flags gains what that start reports
  // (kFlagDefaultStart). One epoch
  // whose frame is the pixel grid (J = 1, flux scale 1) is fitted by the single-stamp Fitter: its
  // row is then the grid path's, the centroid taken relative to the frame's reference.
  FitResult fit(std::span<const Observation> epochs, std::size_t first = 0);
  // That start alone.
  ParamVector sky_start(const Observation& epoch, std::uint32_t* flags);
  // The start of a fit of several cutouts: every cutout's adaptive moments carried to the sky
  // (J M J^T) less its PSF's, averaged with weights flux^2 x mean weight (S/N^2), for the centroid,
  // e and radius, so the start has the S/N of all the cutouts, not of one; the amplitudes are
  // sky_start(epochs[first])'s scaled to the mean flux at that radius. One cutout: sky_start.
  ParamVector joint_start(std::span<const Observation> epochs, std::size_t first, std::uint32_t* flags);

 private:
  class Problem;
  Fitter& starter_for(int box_size);  // the single-stamp fitter for that box size (made on first use)
  FitterOptions options_;
  FftPlanCache plans_;  // for the single-stamp fitters' start (the exact renderer plans its own)
  std::map<int, std::unique_ptr<ExactRenderer>> renderers_;
  std::map<int, std::unique_ptr<Fitter>> starters_;  // per box size: moments for the start
  std::unique_ptr<Problem> problem_;
  // The fit with the amplitudes solved linearly (options.project_amplitudes; ProjectedJointProblem).
  bool project_ = false;
  std::unique_ptr<ProjectedJointProblem> projected_;
  std::vector<int> slot_of_cutout_;  // all 0: one band
};

}  // namespace stampede
