// The reconvolution PSF; see reconvolution_psf.hpp.
#include "engine/metacal/reconvolution_psf.hpp"

#include <cmath>

namespace stampede {

bool reconvolution_psf(const PsfModel& psf, const MetacalOptions& options, PsfModel* out, std::string* error) {
  if (psf.kind != PsfKind::kMoffat) {
    if (error)
      *error = std::string("metacal needs a Moffat PSF (psf_input = moffat or moffat_catalog); this PSF is '") +
               psf_kind_name(psf.kind) + "'";
    return false;
  }
  const double e = std::hypot(psf.moffat.e1, psf.moffat.e2);
  const double dilation =
      options.psf_dilation > 0 ? options.psf_dilation : (1 + 2 * options.step) * std::sqrt((1 + e) / (1 - e));
  kernels::MoffatProfile m;
  m.beta = psf.moffat.beta;
  m.fwhm = psf.moffat.fwhm * dilation;
  *out = PsfModel::Moffat(m);
  return true;
}

}  // namespace stampede
