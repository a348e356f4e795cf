// The exact Fourier-space fitting renderer: pixel values of bulge + disc convolved with the PSF and
// the pixel box, drawn at data resolution from their continuous transform (kernels/kspace_render.hpp
// has the maths and the term loop). No sub-pixel grid, so no cusp sampling and no discretised
// model: the only approximations are the Sérsic table (~1e-10 of the flux), the PSF term
// tolerance and the period N (the light of the untruncated wings that wraps around).
//
// Per render: one pass over the PSF's term list fills the half-spectra of the model or of the
// component and derivative images, then one c2r inverse FFT per image on the N x N periodic grid;
// the stamp is the grid's corner, stamp pixel (x, y) = grid sample (x, y). The periodic grid holds
// the light of the galaxy's copies at multiples of N; for PSFs with finite second moments that
// light is subtracted (kernels/wrapped_wings.hpp: the copies' far wings blurred to second order,
// interpolated from Chebyshev nodes), which lets N be a few stamp widths smaller.
//
// One renderer per thread (it owns its FFTW plan and scratch); the term list and the Sérsic
// tables are immutable and shared read-only.
#pragma once

#include <array>
#include <memory>
#include <string>
#include <vector>

#include "engine/model/galaxy_model.hpp"
#include "engine/model/pixel_frame.hpp"
#include "engine/model/psf_model.hpp"
#include "engine/render/fft_plans.hpp"
#include "engine/render/render_options.hpp"
#include "engine/render/exact_psf.hpp"
#include "engine/render/renderer.hpp"
#include "kernels/kspace_render.hpp"
#include "kernels/wrapped_wings.hpp"

namespace stampede {


// The period rule: N = kernels::fft_friendly_size(stamp_size + kExactPeriodMargin) (39 -> 96,
// 25 -> 84, 48 -> 105) with the copies' light subtracted, for PSFs with finite second moments.
// The margin trades the render's cost (terms and FFTs grow as N^2) against the light the
// subtraction leaves (exact_renderer_test, WrappedLight), which grows as the copies come nearer:
// most for |e| = 0.7, whose copies' light has singularities close to the stamp along the minor
// axis, where the Chebyshev interpolation converges slowly. PSFs without finite second moments
// (the Airy disc, Moffat beta <= 2) need the uncorrected rule, kernels::fft_friendly_size(4
// stamp_size): their wings are no small correction to subtract. Figures: docs/performance.md,
// "The exact renderer's constants".
inline constexpr int kExactPeriodMargin = 57;
// Chebyshev nodes per stamp axis for the copies beyond the first ring: their light varies by a
// factor of a few across the stamp, so 6 nodes leave what 12 would (exact_renderer_test,
// WrappedLight; docs/performance.md) at a quarter of the evaluations.
inline constexpr int kFarWrapNodes = 6;
int exact_period(int stamp_size);
// The surrogate's period rule (ExactRenderOptions::surrogate_period 0).
inline constexpr int kSurrogatePeriodMargin = 25;
int exact_surrogate_period(int stamp_size);
int exact_uncorrected_period(int stamp_size);

// The de Vaucouleurs (n = 4) transform table, built once per process on first use (thread-safe)
// and immutable after (294 quadrature nodes to q = 2,113, resampled into 784 intervals): the
// quadrature costs far more than a fit (docs/performance.md, "The exact renderer's constants").
std::shared_ptr<const kernels::SersicKTable> de_vaucouleurs_k_table();
// A table for any index n >= 1 covering q = k r_e up to q_max (nodes computed in parallel).
std::shared_ptr<const kernels::SersicKTable> build_sersic_k_table(double n, double q_max);
// The table for index n: the n = 4 one, or one built on first use and kept (thread-safe).
std::shared_ptr<const kernels::SersicKTable> sersic_k_table(double n);

class ExactRenderer final : public Renderer {
 public:
  // render: stamp_size and simd (upsampling only sets the model's radius softening, which is the
  // upsampled renderer's, radius_softening / upsampling pixels, so both renderers fit one model).
  // render.exact: this renderer's own options.
  ExactRenderer(const RenderOptions& render, const ModelOptions& model);
  ~ExactRenderer() override;
  ExactRenderer(const ExactRenderer&) = delete;
  ExactRenderer& operator=(const ExactRenderer&) = delete;

  int stamp_size() const override { return stamp_size_; }
  std::shared_ptr<const PreparedPsf> prepare_psf(const PsfModel& psf, std::string* error) override;
  void set_psf(std::shared_ptr<const PreparedPsf> psf) override;
  RenderStatus render(const ParamVector& p, std::span<double> model) override;
  RenderStatus render_with_jacobian(const ParamVector& p, std::span<const Param> free, std::span<double> model,
                                    std::span<double* const> jacobian) override;
  RenderStatus render_components(const ParamVector& p, std::span<double> bulge, std::span<double> disc) override;
  bool effective_params(const ParamVector& p, ParamVector* out) const override;
  void component_fluxes(const ParamVector& p, double* bulge, double* disc) const override;
  // This renderer on the surrogate's period and tolerance, when the options ask for one and the
  // current PSF was prepared with one.
  Renderer* surrogate() override { return exact_surrogate(); }
  // The same, as what it is (a multi-epoch fit draws each cutout with its box's renderer or this).
  ExactRenderer* exact_surrogate() { return surrogate_ && psf_ && psf_->surrogate() ? surrogate_.get() : nullptr; }

  // Any frame (Renderer::set_frame), carried exactly; the identity draws as without a frame.
  bool takes_frames() const override { return true; }
  void set_frame(const PixelFrame& frame) override;  // allocates nothing
  const PixelFrame& frame() const { return frame_; }

  int period() const { return n_; }
  const GalaxyModel& galaxy_model() const { return model_; }
  const ExactPsf* psf() const { return psf_.get(); }
  // The copies' light is subtracted (the PSF's blur moments are finite and the option is on).
  bool corrects_wrap() const { return psf_ && psf_->finite_blur() && options_.wrap_rings > 0; }

 private:
  // The kernels' per-render parameters and the components' real-space forms; false when no model
  // exists for p.
  bool prepare(const ParamVector& p, kernels::KSpaceModel* m, ModelComponents* comp);
  // An image PSF's transform times spectrum k, bin by bin (nothing for analytic PSFs).
  void apply_bin_factor(int k);
  // Inverse FFT of spectrum k (after apply_bin_factor) into grid image k, and the stamp cut from it.
  void inverse(int k, double* stamp);
  // Subtracts the copies' light: from the model (jacobian false), or from the component images
  // and the five shape derivative images (shape[k] null: not wanted).
  // m: this render's transform parameters (for the components' flux per amplitude).
  void subtract_wrap(const ModelComponents& comp, const kernels::KSpaceModel& m, double* model);
  void subtract_wrap(const ModelComponents& comp, const kernels::KSpaceModel& m, double* bulge, double* disc,
                     const std::array<double*, 5>& shape);
  // The copies each component needs, split between the two wrap grids.
  void find_copies(const ModelComponents& comp, const kernels::KSpaceModel& m);

  // The model's components carried into the frame's pixels (identity: untouched).
  void to_frame_pixels(ModelComponents* comp) const;

  int stamp_size_;
  int n_;
  PixelFrame frame_;
  double pixel_area_ = 1;  // |det J|: model units (arcsec^2) per pixel
  std::array<std::vector<double>, 2> position_stamps_;  // d/dx0, d/dy0 in pixels, combined into d/du0, d/dv0
  ExactRenderOptions options_;
  GalaxyModel model_;
  std::shared_ptr<const ExactPsf> psf_;
  std::shared_ptr<const kernels::SersicKTable> bulge_table_;
  double bulge_index_ = 0;
  const kernels::KSpaceKernels* kernels_;
  const kernels::WrapKernels* wrap_kernels_;
  void* column_plan_ = nullptr;  // fftw_plan: the columns' c2c inverse, complex_ into columns_
  void* row_plan_ = nullptr;     // fftw_plan: the stamp rows' c2r from columns_ into grid_
  int row_stride_ = 0;
  double* spectrum_re(int k) const { return static_cast<double*>(spectra_[k].data()); }
  double* spectrum_im(int k) const { return spectrum_re(k) + spectrum_size_; }
  std::size_t spectrum_size_ = 0;  // n * row_stride
  // The kernels' output, split complex (real, then imaginary), rows of row_stride_.
  std::array<AlignedBuffer, kernels::kNumKSpaceImages> spectra_;
  // One interleaved half-spectrum, transposed ((N/2 + 1) columns of N), and its columns' inverse;
  // reused per inverse.
  AlignedBuffer complex_, columns_;
  AlignedBuffer grid_;     // the inverse's stamp_size rows of N, reused per inverse
  // Per render: the bins' phases (row_stride columns, n rows) and the aliases' (KSpaceModel).
  std::vector<double> bin_x_re_, bin_x_im_, bin_y_re_, bin_y_im_, alias_re_, alias_im_;
  std::array<std::vector<double>, 2> component_stamps_;  // bulge, disc per unit amplitude
  // The copies' light at Chebyshev nodes, interpolated to the stamp: [0] the first ring of copies
  // on render.exact.wrap_nodes nodes per axis, [1] the farther rings (at >= 2 N - stamp from it, a
  // de Vaucouleurs wing varies by a factor of a few across the stamp) on kFarWrapNodes.
  struct WrapGrid {
    WrapGrid() = default;
    WrapGrid(int stamp_size, int nodes, kernels::Isa isa, std::size_t copies);
    kernels::ChebyshevStamp grid;
    std::vector<double> node_x, node_y;  // the nodes^2 Chebyshev points, row by row
    std::vector<double> values;          // per wrap image: nodes^2 values
    std::vector<double> scratch;         // nodes * stamp_size
    std::vector<kernels::CopyOffset> bulge, disc;  // this grid's copies, reserved for every ring
  };
  std::array<WrapGrid, 2> wrap_;
  std::unique_ptr<ExactRenderer> surrogate_;
};

}  // namespace stampede
