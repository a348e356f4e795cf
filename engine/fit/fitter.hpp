// Fits one postage stamp with the im3shape model: starting point from adaptive moments, then
// Levenberg-Marquardt on the analytic Jacobian, over the shape parameters with the two
// amplitudes solved linearly at each trial shape (project_amplitudes), or over every free
// parameter jointly. One Fitter per thread; buffers are allocated at construction, none per stamp.
#pragma once

#include <array>
#include <memory>
#include <span>
#include <string>
#include <vector>

#include "engine/fit/fit_result.hpp"
#include "engine/fit/fit_units.hpp"
#include "engine/fit/observation.hpp"
#include "engine/model/galaxy_model.hpp"
#include "engine/model/parameters.hpp"
#include "engine/render/fft_plans.hpp"
#include "engine/render/render_options.hpp"
#include "engine/render/renderer.hpp"
#include "engine/render/renderer_factory.hpp"
#include "engine/solver/levenberg_marquardt.hpp"
#include "kernels/aligned_vector.hpp"
#include "kernels/least_squares.hpp"

namespace stampede {

struct FitterOptions {
  RendererKind renderer = RendererKind::kAuto;
  RenderOptions render;
  ModelOptions model;
  LmOptions lm;
  ParameterSet params;
  double noise_sigma = 0.0;  // per-pixel noise when no weight map is given; 0 = unweighted (noise-free data)
  // Solve the two amplitudes linearly at every trial shape (variable projection) when both are
  // free and unbounded; false: Levenberg-Marquardt over all free parameters jointly (the paper's).
  bool project_amplitudes = true;
  // Iterate first on the renderer's surrogate (Renderer::surrogate), when it has one, until this
  // relative chi2 change per pixel (levmar_eps4's rule), then on the renderer itself from there
  // until lm's rules hold, a Jacobian point whose Gauss-Newton step predicts no more than eps4
  // counting as converged: the optimum, errors and chi2 are the renderer's own.
  double surrogate_eps4 = 1e-6;

  bool IsValid(std::string* why) const;
};

// Whether fits of these options solve the amplitudes linearly (project_amplitudes, both amplitudes
// free and unbounded, and some other parameter free): the single-stamp fit and the joint fits over
// cutouts and bands (engine/fit/projected_joint_problem) alike.
bool projects_amplitudes(const FitterOptions& options);

class Fitter {
 public:
  // options must be valid. psf (prepared by a renderer of options.renderer's kind and options) may
  // be null (it could not be built): every fit then reports kPsfFailure. `plans` must outlive it.
  Fitter(const FitterOptions& options, std::shared_ptr<const PreparedPsf> psf, FftPlanCache& plans);

  ~Fitter();

  // pixels: stamp_size^2, row-major. weight: empty (use noise_sigma) or, per pixel, what `kind`
  // says, 0 masking a pixel.
  FitResult fit(std::span<const double> pixels, std::span<const double> weight = {},
                WeightKind kind = WeightKind::kInverseVariance);
  // As fit(), starting from `start` (a full parameter vector) instead of the moments.
  FitResult fit_from(std::span<const double> pixels, std::span<const double> weight, const ParamVector& start);

  // The starting point fit() would use (exposed for tests and diagnostics); flags may gain kFlagDefaultStart.
  ParamVector starting_point(std::span<const double> pixels, std::span<const double> weight, std::uint32_t* flags);

  // Swaps the PSF for the following fits (null: they report kPsfFailure). Allocates nothing.
  void set_psf(std::shared_ptr<const PreparedPsf> psf);

  // The renderer the fits use, e.g. to prepare PSFs for set_psf (Renderer::prepare_psf).
  Renderer& renderer() { return *renderer_; }
  const FitterOptions& options() const { return options_; }

 private:
  class Problem;
  class ProjectedProblem;
  class Solving;
  // The PSF and weight checks fit() and fit_from() share; false, with *r filled, when nothing can be fitted.
  bool ready(std::span<const double> pixels, std::span<const double> weight, WeightKind kind, FitResult* r,
             std::uint32_t* flags);
  // Sets units_ from the stamp and fills weight_ and the problem's data in them; returns a status
  // other than kOk when nothing can be fitted.
  FitStatus prepare_weights(std::span<const double> pixels, std::span<const double> weight, WeightKind kind,
                            std::uint32_t* flags);
  // start, and the fit inside, in the units of units_ (amplitudes over units_.data).
  FitResult run(const ParamVector& start, std::uint32_t flags);
  ParamVector start_from_prepared(std::uint32_t* flags);
  void solve_start_amplitudes(ParamVector* p);
  // Sets free parameter q to x (internal units) in *p; false outside its bounds (stated in data
  // units; the units are powers of two, so the comparison is exact).
  bool set_within_bounds(Param q, double x, ParamVector* p) const;

  FitterOptions options_;
  std::shared_ptr<const PreparedPsf> psf_;
  std::unique_ptr<Renderer> renderer_;
  Renderer* active_ = nullptr;  // what the problems draw with: renderer_ or its surrogate
  const kernels::LeastSquaresKernels* least_squares_;  // options_.render.simd's build
  std::unique_ptr<Problem> problem_;
  std::unique_ptr<ProjectedProblem> projected_;
  FitUnits units_;                         // of the stamp being fitted
  kernels::AlignedVector<double> weight_;  // in units_.weight
  std::vector<double> start_bulge_, start_disc_, start_model_, zeros_;
  std::array<Param, kNumParams> free_{};
  int num_free_ = 0;
  // Projected fits: indices into free_ of the shape parameters and of the two amplitudes.
  bool project_ = false;
  std::array<int, kNumParams> shape_{};
  int num_shape_ = 0;
  std::array<int, 2> amplitude_{};
  ParamVector lower_{}, upper_{};
};

}  // namespace stampede
