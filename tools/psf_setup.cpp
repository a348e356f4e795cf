// The run's shared PSF; see psf_setup.hpp.
#include "tools/psf_setup.hpp"

#include <stdexcept>
#include <string>

#include "io/fits_file.hpp"

namespace stampede::tools {

SharedPsf build_shared_psf(const io::RunConfig& cfg, const GridGeometry& geometry, FftPlanCache& plans) {
  SharedPsf out;
  PsfOptions& psf = out.options;
  if (cfg.psf_input == io::PsfInput::kMoffat) {
    psf.type = PsfType::kMoffat;
    psf.moffat = cfg.moffat;
    out.e1 = cfg.moffat.e1, out.e2 = cfg.moffat.e2, out.fwhm = cfg.moffat.fwhm;
  } else if (cfg.psf_input == io::PsfInput::kAiry) {
    psf.type = PsfType::kAiry;
    psf.airy = cfg.airy;
    out.e1 = out.e2 = 0.0;
    out.fwhm = 1.028993969962188 * cfg.airy.lambda_over_d;  // FWHM of the unobscured Airy disc
  } else if (cfg.psf_input == io::PsfInput::kImage) {
    psf.type = PsfType::kImage;
    io::FitsFile f = io::FitsFile::open_read(cfg.psf_image);
    const auto shape = f.image_shape();
    auto img = std::make_shared<PsfImage>();
    img->nx = static_cast<int>(shape.nx);
    img->ny = static_cast<int>(shape.ny);
    img->pixels = f.read_image();
    img->oversampling = cfg.psf_upsampling;
    img->pixel_integrated = cfg.psf_pixel_integrated;
    psf.image = img;
  } else {
    throw std::logic_error("build_shared_psf: psf_input = moffat_catalog has no shared PSF");
  }
  std::string error;
  out.kernel = PsfKernel::build(psf, geometry, plans, &error);
  if (!out.kernel)
    throw std::runtime_error("PSF (psf_input = " + std::string(io::psf_input_name(cfg.psf_input)) + "): " + error);
  return out;
}

}  // namespace stampede::tools
