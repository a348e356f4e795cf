// What the joint fits over observations (ObjectFitter's problems) share besides
// the solve (engine/fit/solve.hpp): the scratch a cutout is drawn into, the check of their cutouts,
// and whether any cutout's renderer has a surrogate to start on.
#pragma once

#include <array>
#include <functional>
#include <span>
#include <vector>

#include "engine/fit/fit_result.hpp"
#include "engine/fit/fit_units.hpp"
#include "engine/fit/fitter.hpp"
#include "engine/fit/observation.hpp"
#include "engine/fit/solve.hpp"
#include "kernels/least_squares.hpp"

namespace stampede {

// The cutouts' data and weights as the least-squares kernels take them, each cutout's flux scale s
// folded in: sum w (d - s m)^2 = sum (w s^2) (d/s - m)^2, and the normal equations of the columns
// s c likewise, so one kernel call per cutout serves every joint fit; then in the fit's units
// (d/s and w s^2 over powers of two, an exact change). Copies only the cutouts whose scale or units
// are not 1, into storage that grows to the largest object seen and is then reused.
class KernelCutouts {
 public:
  void reset(std::span<const Observation> epochs, const FitUnits& units);
  std::span<const double> data(std::size_t c) const { return data_[c]; }
  std::span<const double> weight(std::size_t c) const { return weight_[c]; }

 private:
  std::vector<std::span<const double>> data_, weight_;
  std::vector<std::vector<double>> scaled_data_, scaled_weight_;
};

// One cutout's sums at a model and its columns: chi2, the signal sum w s^2 m^2, and the normal
// equations (alpha ncol x ncol row-major and symmetric, beta).
struct CutoutSums {
  double chi2 = 0, signal = 0;
  std::array<double, kMaxFree * kMaxFree> alpha{};
  std::array<double, kMaxFree> beta{};
};

// A cutout's model and derivative images, grown to the largest box once and then reused.
class CutoutScratch {
 public:
  // `r` set to e's PSF and frame, the scratch sized for e; returns the renderer to draw with (r's
  // exact surrogate when `surrogate` and r has one).
  Renderer& select(Renderer& r, const Observation& e, bool surrogate);
  std::span<double> model() const { return model_span_; }
  const std::vector<double>& derivative(std::size_t k) const { return jacobian_[k]; }
  std::span<double* const> columns(std::size_t n) const { return {columns_.data(), n}; }
  // chi2 of the model drawn here against a cutout's kernel data and weight (KernelCutouts).
  double chi2(const kernels::LeastSquaresKernels& k, std::span<const double> data, std::span<const double> weight) const {
    return k.weighted_chi2(data, model_span_, weight);
  }
  // The sums of the model and first ncol columns drawn here against them; false when not finite.
  bool sums(const kernels::LeastSquaresKernels& k, std::span<const double> data, std::span<const double> weight, int ncol,
            CutoutSums* out);

 private:
  std::vector<double> zeros_;  // the signal's data: sum w m^2 is the chi2 of the model against zero
  std::vector<double> model_;
  std::span<double> model_span_;
  std::array<std::vector<double>, kNumParams> jacobian_;
  std::array<double*, kNumParams> columns_{};
};

// What every joint problem holds of its cutouts (ObjectFitter's and the projected one): the cutouts,
// the fit's units and the kernel data in them, the renderer per box size, the scratch they are
// drawn into, the unmasked pixel count and the chi2 that counts as exact.
//
// The units (FitUnits) are one pair per object, over every cutout's used pixels as the model sees
// them (d/s, w s^2): the amplitudes are in the reference zero point's units, so that is the scale
// they take. Every chi2, sum and amplitude the problems see is in these units; the caller states
// the start in them (FitUnits::to_internal) and reports back in data units.
class JointCutouts {
 public:
  using RendererFor = std::function<Renderer&(int box_size)>;
  JointCutouts(RendererFor renderer_for, const kernels::LeastSquaresKernels& kernels)
      : renderer_for_(std::move(renderer_for)), kernels_(kernels) {}
  void reset(std::span<const Observation> epochs);
  std::span<const Observation> epochs() const { return epochs_; }
  const FitUnits& units() const { return units_; }
  int pixels() const { return pixels_; }
  // As the single-stamp fit's: a model within ~1e-7 rms of the data, relative to it, is exact for
  // any purpose (noise-free data would otherwise keep chi2 halving to the iteration limit). In the
  // fit's units.
  double negligible_chi2() const { return negligible_chi2_; }
  // Draw with each cutout renderer's surrogate where it has one (the surrogate stage).
  void use_surrogates(bool on) { surrogates_ = on; }
  // Cutout c's renderer, set to its PSF and frame (its surrogate in the surrogate stage), with the
  // scratch sized for it.
  Renderer& select(std::size_t c) { return scratch_.select(renderer_for_(epochs_[c].box_size), epochs_[c], surrogates_); }
  // Cutout c's chi2 at p; false when no model exists there.
  bool chi2(std::size_t c, const ParamVector& p, double* chi2);
  // Cutout c's sums at p over the free parameters; false when no model exists there.
  bool sums(std::size_t c, const ParamVector& p, std::span<const Param> free, CutoutSums* out);

 private:
  RendererFor renderer_for_;
  const kernels::LeastSquaresKernels& kernels_;
  std::span<const Observation> epochs_;
  FitUnits units_;
  KernelCutouts data_;
  CutoutScratch scratch_;
  int pixels_ = 0;
  double negligible_chi2_ = 0;
  bool surrogates_ = false;
};

// kPsfFailure when a cutout has no PSF (else kOk); throws std::invalid_argument naming `who` when a
// cutout's pixels or weights are not box_size^2.
FitStatus check_cutouts(std::span<const Observation> epochs, const char* who);

// Whether any cutout's PSF gives its renderer (renderer_for(box_size)) an exact surrogate: the
// solve then starts on the surrogates.
template <class RendererFor>
bool any_surrogate(std::span<const Observation> epochs, RendererFor&& renderer_for) {
  bool coarse = false;
  for (const Observation& e : epochs) {
    Renderer& r = renderer_for(e.box_size);
    r.set_psf(e.psf);
    coarse = coarse || r.surrogate() != nullptr;
  }
  return coarse;
}

}  // namespace stampede
