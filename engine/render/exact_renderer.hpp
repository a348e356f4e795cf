// The exact Fourier-space fitting renderer: pixel values of bulge + disc convolved with the PSF and
// the pixel box, drawn at data resolution from their continuous transform (kernels/kspace_render.hpp
// has the maths and the term loop). No sub-pixel grid, so no cusp sampling and no discretised
// model: the only approximations are the Sérsic table (~1e-10 of the flux), the PSF term
// tolerance and the period N (the light of the untruncated wings that wraps around).
//
// Per render: one pass over the PSF's term list fills the half-spectra of the model or of the
// component and derivative images, then one c2r inverse FFT per image on the N x N periodic grid;
// the stamp is the grid's corner, stamp pixel (x, y) = grid sample (x, y).
//
// One renderer per thread (it owns its FFTW plan and scratch); the term list and the Sérsic
// tables are immutable and shared read-only.
#pragma once

#include <array>
#include <memory>
#include <string>
#include <vector>

#include "engine/model/galaxy_model.hpp"
#include "engine/model/psf_model.hpp"
#include "engine/render/fft_plans.hpp"
#include "engine/render/render_options.hpp"
#include "engine/render/renderer.hpp"
#include "kernels/kspace_render.hpp"

namespace stampede {

struct ExactRenderOptions {
  // Alias terms whose |PSF transform x pixel sinc| (PPi, with PPi(0) = 1) is at most this are
  // dropped (by blocks of 8 columns: a block is kept when any of its values exceeds it). Measured
  // on the GalSim render_cases discs (no wrap to speak of at exact_period): worst |diff| / peak
  // 1.0e-5 at 1e-5, 7.7e-7 at 1e-6, 3.9e-8 at 1e-7, 1.2e-8 at 1e-8 (GalSim's own floor); the
  // fiducial PSF on the 160-pixel period needs 29,024 / 37,176 / 44,792 / 55,792 terms. Default
  // 1e-7: its error is 1 % of the 1e-5 budget, 17 % more terms than 1e-6.
  double psf_tolerance = 1e-7;
  // Period N of the grid in pixels; 0: exact_period(stamp_size).
  int period = 0;
  FftPlanning planning = FftPlanning::kEstimate;  // kMeasure: faster plans, bitwise only with wisdom

  bool IsValid(std::string* why) const;
};

// The period rule: N = kernels::fft_friendly_size(4 stamp_size) (39 -> 160, 25 -> 100, 48 -> 192). The
// de Vaucouleurs wings decide it: their light wrapped onto the stamp by the copies at distance N,
// against GalSim's unwrapped stamps (worst |diff| / peak over the 22 render_cases, set by the
// r_e = 2.5-3 bulges in 39-pixel stamps): N = 60: 7.4e-4, 72: 3.3e-4, 80: 2.1e-4, 96: 9.3e-5,
// 120: 3.4e-5, 160: 9.0e-6, 240: 1.2e-6; discs alone: 3.4e-6 at 60, 2.9e-7 at 80, 1.6e-8 at 120.
// The wrapped fraction grows with r_e (see exact_renderer_test, WrappedLight).
int exact_period(int stamp_size);

// The term list of a PSF on an N x N grid: the only PSF-specific code of this renderer. Analytic
// PSFs only (Moffat, truncated or not, and the unobscured Airy disc); throws std::invalid_argument
// for others.
std::shared_ptr<const kernels::KSpaceTerms> build_kspace_terms(const PsfModel& psf, int period, double tolerance);

// The de Vaucouleurs (n = 4) transform table, built once per process on first use (thread-safe)
// and immutable after (294 nodes to q = 2,113: 2.2-3.8 s on this shared 2-core machine).
std::shared_ptr<const kernels::SersicKTable> de_vaucouleurs_k_table();
// A table for any index n >= 1 covering q = k r_e up to q_max (nodes computed in parallel).
std::shared_ptr<const kernels::SersicKTable> build_sersic_k_table(double n, double q_max);

// Not yet behind the Renderer seam (engine/render/renderer.hpp): that needs the prepared-PSF form
// (the term list plus the PSF's adaptive moments for the fitter's start) and a period that does
// not cost 1.9x of the upsampled renderer's time (the wrap above), both open in issue 16.
class ExactRenderer {
 public:
  // render: stamp_size, simd and upsampling (the model's radius softening is the upsampled
  // renderer's, radius_softening / upsampling pixels, so both renderers fit the same model).
  // bulge_table: the transform of the bulge's index (p[kBulgeIndex]); null when it is 1.
  ExactRenderer(const RenderOptions& render, const ModelOptions& model, const ExactRenderOptions& options,
                std::shared_ptr<const kernels::KSpaceTerms> terms,
                std::shared_ptr<const kernels::SersicKTable> bulge_table, double bulge_index = 4.0);
  ~ExactRenderer();
  ExactRenderer(const ExactRenderer&) = delete;
  ExactRenderer& operator=(const ExactRenderer&) = delete;

  int stamp_size() const { return stamp_size_; }
  RenderStatus render(const ParamVector& p, std::span<double> model);
  RenderStatus render_with_jacobian(const ParamVector& p, std::span<const Param> free, std::span<double> model,
                                    std::span<double* const> jacobian);

  const GalaxyModel& galaxy_model() const { return model_; }
  // Swaps the PSF (a term list for the same period); for per-object PSFs.
  void set_terms(std::shared_ptr<const kernels::KSpaceTerms> terms);
  int period() const { return n_; }
  const kernels::KSpaceTerms& terms() const { return *terms_; }

 private:
  // The kernels' per-render parameters; false when no model exists for p.
  bool prepare(const ParamVector& p, kernels::KSpaceModel* m);
  // Inverse FFT of spectrum k into grid image k, and the stamp cut from it.
  void inverse(int k, double* stamp);

  int stamp_size_;
  int n_;
  GalaxyModel model_;
  std::shared_ptr<const kernels::KSpaceTerms> terms_;
  std::shared_ptr<const kernels::SersicKTable> bulge_table_;
  double bulge_index_;
  const kernels::KSpaceKernels* kernels_;
  void* plan_ = nullptr;  // fftw_plan: split-complex c2r, rows of terms_->row_stride
  double* spectrum_re(int k) const { return static_cast<double*>(spectra_[k].data()); }
  double* spectrum_im(int k) const { return spectrum_re(k) + spectrum_size_; }
  std::size_t spectrum_size_ = 0;  // n * row_stride
  std::array<AlignedBuffer, kernels::kNumKSpaceImages> spectra_;  // split complex: real, then imaginary
  AlignedBuffer grid_;  // one N x N real image, reused per inverse
  std::vector<double> phase_x_re_, phase_x_im_, phase_y_re_, phase_y_im_;
  std::array<std::vector<double>, 2> component_stamps_;  // bulge, disc per unit amplitude
};

}  // namespace stampede
