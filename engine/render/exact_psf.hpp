// The exact renderer's prepared PSF: the PSF x pixel transform as a term list on the renderer's
// period, the blur's second moments for the wrap correction, and the adaptive moments the
// fitter's start needs. Built once per distinct PSF, immutable, shared by every thread.
#pragma once

#include <memory>
#include <string>
#include <vector>

#include "engine/model/psf_model.hpp"
#include "engine/render/renderer.hpp"
#include "kernels/kspace_render.hpp"
#include "kernels/wrapped_wings.hpp"

namespace stampede {

class ExactPsf final : public PreparedPsf {
 public:
  ExactPsf(std::shared_ptr<const kernels::KSpaceTerms> terms, bool finite_blur, const kernels::BlurMoments& blur,
           double xx, double xy, double yy)
      : terms_(std::move(terms)), finite_blur_(finite_blur), blur_(blur), xx_(xx), xy_(xy), yy_(yy) {}
  // An image PSF: the term list is the band limit alone (every bin of the principal zone, no
  // aliases), and the samples' transform D(k) (complex: a PSF image need not be centrosymmetric)
  // multiplies each bin after the term loop, split complex in n rows of row_stride.
  ExactPsf(std::shared_ptr<const kernels::KSpaceTerms> terms, const kernels::BlurMoments& blur, double xx, double xy,
           double yy, std::vector<double> bin_re, std::vector<double> bin_im)
      : terms_(std::move(terms)),
        finite_blur_(true),
        blur_(blur),
        xx_(xx),
        xy_(xy),
        yy_(yy),
        bin_re_(std::move(bin_re)),
        bin_im_(std::move(bin_im)) {}
  // The same PSF prepared for the renderer's surrogate (exact_renderer.hpp), or null.
  ExactPsf(const ExactPsf& base, std::shared_ptr<const ExactPsf> surrogate)
      : ExactPsf(base) {
    surrogate_ = std::move(surrogate);
  }
  const std::shared_ptr<const ExactPsf>& surrogate() const { return surrogate_; }
  bool has_bin_factor() const { return !bin_re_.empty(); }
  const double* bin_re() const { return bin_re_.data(); }
  const double* bin_im() const { return bin_im_.data(); }
  double xx() const override { return xx_; }
  double xy() const override { return xy_; }
  double yy() const override { return yy_; }
  const kernels::KSpaceTerms& terms() const { return *terms_; }
  int period() const { return terms_->n; }
  // False for PSFs whose second moments diverge (the Airy disc, Moffat beta <= 2): their wings
  // are not a small correction to the galaxy's, so the copies' light cannot be subtracted.
  bool finite_blur() const { return finite_blur_; }
  // Second moments of PSF x pixel box, pixels^2 (meaningful when finite_blur()).
  const kernels::BlurMoments& blur() const { return blur_; }

 private:
  std::shared_ptr<const kernels::KSpaceTerms> terms_;
  bool finite_blur_;
  kernels::BlurMoments blur_;
  double xx_, xy_, yy_;
  std::vector<double> bin_re_, bin_im_;
  std::shared_ptr<const ExactPsf> surrogate_;
};

// The term list of a PSF on an N x N grid (terms with |PSF x pixel sinc| <= tolerance dropped by
// blocks). Analytic PSFs only (Moffat, truncated or not, and the unobscured Airy disc); throws
// std::invalid_argument for others.
std::shared_ptr<const kernels::KSpaceTerms> build_kspace_terms(const PsfModel& psf, int period, double tolerance);

// Second moments of PSF x pixel; false when the PSF's diverge.
bool blur_moments(const PsfModel& psf, kernels::BlurMoments* out);

// Everything above plus the adaptive moments (of PSF x pixel drawn on the period from the terms);
// null, with *error, when the PSF is invalid or of a kind the term list cannot take. Image PSFs
// (psf_model.hpp's PsfImage) must hold pixel integrals at the data's sampling (oversampling 1,
// pixel_integrated: what PSFEx gives at PSF_SAMP = 1) and be square: their transform is taken as
// band-limited (the samples' own, zero beyond the pixel Nyquist frequency, as PsfImage::transform
// defines it), so the galaxy is not aliased and no pixel response is added.
std::shared_ptr<const ExactPsf> build_exact_psf(const PsfModel& psf, int period, double tolerance,
                                                std::string* error);

}  // namespace stampede
