// The reconvolution PSF; see reconvolution_psf.hpp.
#include "engine/metacal/reconvolution_psf.hpp"

#include <cmath>
#include <vector>

#include "engine/common/number_text.hpp"
#include "kernels/moments.hpp"

namespace stampede {
namespace {

PsfModel round_moffat(double beta, double fwhm) {
  kernels::MoffatProfile m;
  m.beta = beta;
  m.fwhm = fwhm;
  return PsfModel::Moffat(m);
}

}  // namespace

std::shared_ptr<const MetacalFilters> reconvolution_filters(const PsfModel& psf, const MetacalOptions& options,
                                                            int period, std::string* error) {
  if (psf.kind == PsfKind::kMoffat) {
    const double e = std::hypot(psf.moffat.e1, psf.moffat.e2);
    const double dilation =
        options.psf_dilation > 0 ? options.psf_dilation : (1 + 2 * options.step) * std::sqrt((1 + e) / (1 - e));
    return MetacalFilters::build(psf, round_moffat(psf.moffat.beta, psf.moffat.fwhm * dilation), options.step, period,
                                 error);
  }
  if (psf.kind == PsfKind::kImage && psf.image) {
    const PsfImage& im = *psf.image;
    if (im.nx != im.ny) {
      if (error) *error = "metacal needs a square PSF image, not " + std::to_string(im.nx) + " x " + std::to_string(im.ny);
      return nullptr;
    }
    const std::vector<double> ones(im.pixels.size(), 1.0);
    const kernels::ImageMoments mom = kernels::adaptive_moments(im.pixels, ones, im.nx);
    if (!mom.valid) {
      if (error) *error = "metacal: the PSF image has no adaptive moments (no positive flux, or no shape)";
      return nullptr;
    }
    // The larger eigenvalue of the covariance, in data pixels^2.
    const double o2 = static_cast<double>(im.oversampling) * im.oversampling;
    const double tr = (mom.xx + mom.yy) / o2, det = (mom.xx * mom.yy - mom.xy * mom.xy) / (o2 * o2);
    const double lambda = 0.5 * tr + std::sqrt(std::max(0.0, 0.25 * tr * tr - det));
    // The Gaussian-equivalent FWHM of the major axis overstates a Moffat core's: start below it
    // and widen until every filter is bounded, which finds the narrowest Gamma that serves.
    const double major = 2.3548 * std::sqrt(lambda);
    std::string why;
    if (options.psf_dilation > 0) {
      auto f = MetacalFilters::build(psf, round_moffat(3.0, major * options.psf_dilation), options.step, period, &why);
      if (!f && error) *error = why;
      return f;
    }
    double fwhm = 0.7 * major;
    for (int attempt = 0; attempt < 40; ++attempt, fwhm *= 1.03) {
      auto f = MetacalFilters::build(psf, round_moffat(3.0, fwhm), options.step, period, &why);
      if (f) return f;
    }
    if (error) *error = why + " (round Moffats up to FWHM " + number_text(fwhm / 1.03) + " px tried)";
    return nullptr;
  }
  if (error)
    *error = std::string("metacal needs a Moffat or image PSF (psf_input = moffat, moffat_catalog or image); this PSF "
                         "is '") + psf_kind_name(psf.kind) + "'";
  return nullptr;
}

}  // namespace stampede
