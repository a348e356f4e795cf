// PSF header keywords; see psf_keys.hpp.
#include "io/psf_keys.hpp"

#include <stdexcept>
#include <string>

#include "engine/common/quoted_value.hpp"
#include "io/fits_error.hpp"

namespace stampede::io {

void write_psf_keys(FitsFile& f, const PsfModel& psf) {
  if (psf.kind == PsfKind::kMoffat) {
    f.write_key("PSFTYPE", std::string(psf_kind_name(psf.kind)), "PSF profile");
    f.write_key("PSFBETA", psf.moffat.beta, "Moffat beta");
    f.write_key("PSFFWHM", psf.moffat.fwhm, "Moffat FWHM (pixels), round profile");
    f.write_key("PSFE1", psf.moffat.e1, "PSF shape, reduced shear g1=(a-b)/(a+b)");
    f.write_key("PSFE2", psf.moffat.e2, "PSF shape, reduced shear g2");
    f.write_key("PSFTRUNC", psf.moffat.truncation, "Moffat truncation radius (0 = none)");
  } else if (psf.kind == PsfKind::kAiry) {
    f.write_key("PSFTYPE", std::string(psf_kind_name(psf.kind)), "PSF profile");
    f.write_key("PSFLOD", psf.airy.lambda_over_d, "Airy lambda/D (pixels)");
    f.write_key("PSFOBSC", psf.airy.obscuration, "Airy central obscuration");
  } else {
    throw std::invalid_argument("write_psf_keys: an image PSF has no header keywords");
  }
}

PsfModel read_psf_keys(FitsFile& f) {
  PsfModel psf;
  const std::string type = f.read_key_string("PSFTYPE").value_or(psf_kind_name(PsfKind::kMoffat));
  if (type == psf_kind_name(PsfKind::kMoffat)) {
    psf.kind = PsfKind::kMoffat;
    psf.moffat = {f.key_double("PSFBETA"), f.key_double("PSFFWHM"), f.key_double("PSFE1"), f.key_double("PSFE2"),
                  f.read_key_double("PSFTRUNC").value_or(0.0)};
  } else if (type == psf_kind_name(PsfKind::kAiry)) {
    psf.kind = PsfKind::kAiry;
    psf.airy.lambda_over_d = f.key_double("PSFLOD");
    psf.airy.obscuration = f.read_key_double("PSFOBSC").value_or(0.0);
  } else {
    throw FitsError(f.describe() + ": header keyword 'PSFTYPE' = " + quoted_value(type) + " is not moffat or airy");
  }
  return psf;
}

std::optional<PsfModel> read_psf_keys_if_present(FitsFile& f) {
  for (const char* key : {"PSFTYPE", "PSFBETA", "PSFLOD"})
    if (f.read_key_string(key)) return read_psf_keys(f);
  return std::nullopt;
}

}  // namespace stampede::io
