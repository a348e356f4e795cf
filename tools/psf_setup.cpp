// The run's shared PSF; see psf_setup.hpp.
#include "tools/psf_setup.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <stdexcept>
#include <string>

#include "io/fits_file.hpp"
#include "kernels/math/airy.hpp"

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
    out.fwhm = kernels::kAiryFwhmOverLambdaOverD * cfg.airy.lambda_over_d;  // FWHM of the unobscured Airy disc
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

namespace {

std::string number(double v) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.10g", v);
  return buf;
}

}  // namespace

std::vector<std::string> psf_differences(const PsfOptions& recorded, const PsfOptions& run) {
  std::vector<std::string> out;
  if (run.type == PsfType::kImage) return out;
  auto type_name = [](PsfType t) { return t == PsfType::kMoffat ? "moffat" : t == PsfType::kAiry ? "airy" : "image"; };
  if (recorded.type != run.type) {
    out.push_back(std::string("PSFTYPE = '") + type_name(recorded.type) + "' (psf_input = " + type_name(run.type) + ")");
    return out;
  }
  auto compare = [&](const char* key, double a, const char* option, double b) {
    if (!(std::abs(a - b) <= 1e-9 * std::max(std::abs(a), std::abs(b))))
      out.push_back(std::string(key) + " = " + number(a) + " (" + option + " = " + number(b) + ")");
  };
  if (run.type == PsfType::kMoffat) {
    compare("PSFBETA", recorded.moffat.beta, "psf_beta", run.moffat.beta);
    compare("PSFFWHM", recorded.moffat.fwhm, "psf_fwhm", run.moffat.fwhm);
    compare("PSFE1", recorded.moffat.e1, "psf_e1", run.moffat.e1);
    compare("PSFE2", recorded.moffat.e2, "psf_e2", run.moffat.e2);
    compare("PSFTRUNC", recorded.moffat.truncation, "psf_truncation", run.moffat.truncation);
  } else {
    compare("PSFLOD", recorded.airy.lambda_over_d, "airy_lambda_over_d", run.airy.lambda_over_d);
    compare("PSFOBSC", recorded.airy.obscuration, "airy_obscuration", run.airy.obscuration);
  }
  return out;
}

}  // namespace stampede::tools
