// Fits one galaxy to its observations: the one fitter of a grid stamp, a MEDS object's epochs and
// its bands (the paper's extension (i); DES Y1's im3shape, and DES Y3/Y6's joint r, i, z fits;
// measurements in docs/multiband.md).
//
// The model lives on the sky's tangent plane (u, v) in arcsec; each observation sees it through its
// own frame (model/pixel_frame), PSF, weights and flux scale, and the fit minimises
//   chi2 = sum over observations c, pixels i of w_ci (d_ci - s_c M(shape, A_band(c))_ci)^2:
// one shape — (u0, v0), e1, e2 and the radius — for every observation, a bulge and a disc
// amplitude per band. The solver's vector is the free parameters in ParameterSet order (the first
// band's amplitudes among them) followed by each further band's free amplitudes, so a one-band fit
// is the plain joint fit over its cutouts. Amplitudes are solved linearly at each trial shape when
// projects_amplitudes(options) (engine/fit/projected_joint_problem).
//
// One observation whose frame is its pixel grid (unit Jacobian, flux scale 1) is a single stamp:
// it is fitted by the single-stamp Fitter (scaled units, its weight kind honoured, any renderer), so
// a grid row and such a MEDS row are the same fit. Observations in other frames need a renderer
// that takes frames (Renderer::takes_frames; renderer = exact or auto).
//
// One fitter per thread; renderers and single-stamp fitters are made per box size on first use
// and kept, so a run allocates only as new box sizes appear.
#pragma once

#include <map>
#include <memory>
#include <span>
#include <vector>

#include "engine/fit/fit_result.hpp"
#include "engine/fit/fitter.hpp"
#include "engine/fit/multi_band_result.hpp"
#include "engine/fit/observation.hpp"
#include "engine/render/fft_plans.hpp"

namespace stampede {

class ProjectedJointProblem;

class ObjectFitter {
 public:
  // options must be valid; options.render.stamp_size is not used (each observation's box is).
  // planning: the single-stamp fits' FFT plans (the renderers' that use FFTs).
  explicit ObjectFitter(const FitterOptions& options, FftPlanning planning = FftPlanning::kEstimate);
  ~ObjectFitter();

  // The renderer for observations of box_size pixels (made on first use), to prepare their PSFs.
  Renderer& renderer_for(int box_size);
  const FitterOptions& options() const { return options_; }

  // Fits an object seen in `n_bands` bands (each observation's `band` in 0..n_bands-1), the shape
  // started from the moments of observations[first] and of all of them (joint_start). *bands, when
  // not empty (n_bands entries), gets each band's part; a band without observations is left out of
  // the fit (its fluxes NaN). With more than one band the result's amplitudes (params) are NaN: they
  // are per band. Result: params, errors and fluxes in sky units; chi2 and S/N summed over the
  // observations; n_pixels the unmasked pixels of all of them. Throws std::invalid_argument for a
  // band out of range, n_bands outside 1..kMaxBands, a `bands` of another size, no observation at
  // `first`, or a renderer that takes no frames given one (naming the option).
  FitResult fit(std::span<const Observation> observations, int n_bands = 1, std::span<BandFit> bands = {},
                std::size_t first = 0);
  // One band's joint fit from `start` (sky units), every observation through its frame.
  FitResult fit_from(std::span<const Observation> observations, const ParamVector& start);

  // The start of one observation alone: its single-stamp moments carried to the sky.
  ParamVector sky_start(const Observation& observation, std::uint32_t* flags);
  // The start of a fit of several observations: every observation's adaptive moments carried to
  // the sky (J M J^T) less its PSF's, averaged with weights flux^2 x mean weight (S/N^2), for the
  // centroid, e and radius, so the start has the S/N of all of them, not of one; the amplitudes are
  // sky_start(observations[first])'s scaled to the mean flux at that radius. One: sky_start.
  ParamVector joint_start(std::span<const Observation> observations, std::size_t first, std::uint32_t* flags);

 private:
  class Problem;
  Fitter& stamp_fitter_for(int box_size);  // the single-stamp fitter for that box size (made on first use)
  // The joint fit from `start` over `slots` bands (slot_of_band: each band's slot, -1 left out),
  // amplitude_start: each slot's amplitudes' start. Several slots: fills bands (when not empty) of
  // those slots.
  FitResult fit_joint(std::span<const Observation> observations, const ParamVector& start,
                      std::span<const ParamVector> amplitude_start, std::span<const int> slot_of_band,
                      std::span<const int> band_of_slot, std::span<BandFit> bands);

  FitterOptions options_;
  FftPlanCache plans_;
  std::map<int, std::unique_ptr<Renderer>> renderers_;
  std::map<int, std::unique_ptr<Fitter>> stamp_fitters_;  // per box size: single stamps and moments starts
  std::unique_ptr<Problem> problem_;
  bool project_ = false;  // amplitudes solved linearly (options.project_amplitudes; ProjectedJointProblem)
  std::unique_ptr<ProjectedJointProblem> projected_;
  std::vector<int> slot_of_cutout_, slot_of_band_, band_of_slot_;
  std::vector<ParamVector> amplitude_start_;
  std::vector<Observation> band_observations_;
};

}  // namespace stampede
