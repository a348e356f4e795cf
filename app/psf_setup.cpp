// The run's shared PSF; see psf_setup.hpp.
#include "app/psf_setup.hpp"

#include "engine/metacal/metacal_imager.hpp"
#include "engine/metacal/reconvolution_psf.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <stdexcept>
#include <string>

#include "engine/common/quoted_value.hpp"
#include "engine/render/renderer_factory.hpp"
#include "io/fits_file.hpp"

namespace stampede::app {

SharedPsf build_shared_psf(const app::RunConfig& config, FftPlanCache& plans) {
  if (config.psf_from_catalogue) throw std::logic_error("build_shared_psf: psf_input = moffat_catalog has no shared PSF");
  SharedPsf out;
  switch (config.psf_kind) {
    case PsfKind::kMoffat: out.model = PsfModel::Moffat(config.moffat); break;
    case PsfKind::kAiry: out.model = PsfModel::Airy(config.airy); break;
    case PsfKind::kGaussian: throw std::logic_error("build_shared_psf: psf_input = gaussian is refused by the config");
    case PsfKind::kImage: {
      io::FitsFile f = io::FitsFile::open_read(config.psf_image);
      const auto shape = f.image_shape();
      auto img = std::make_shared<PsfImage>();
      img->nx = static_cast<int>(shape.nx);
      img->ny = static_cast<int>(shape.ny);
      img->pixels = f.read_image();
      img->oversampling = config.psf_upsampling;
      img->pixel_integrated = config.psf_pixel_integrated;
      out.model = PsfModel::Image(std::move(img));
      break;
    }
  }
  return prepare_shared_psf(out.model, config, plans, "psf_input = " + app::psf_input_value(config));
}

SharedPsf prepare_shared_psf(const PsfModel& model, const app::RunConfig& config, FftPlanCache& plans,
                             const std::string& what) {
  SharedPsf out;
  out.model = model;
  out.e1 = out.model.e1(), out.e2 = out.model.e2(), out.fwhm = out.model.fwhm();
  std::string error;
  out.kind = config.fitter.renderer;
  out.prepared = make_renderer(out.kind, config.fitter.render, config.fitter.model, plans)->prepare_psf(out.model, &error);
  if (out.kind == RendererKind::kAuto) {
    // auto: the exact renderer where it takes the PSF, the upsampled one where it refuses.
    out.kind = RendererKind::kExact;
    if (!out.prepared) {
      std::string upsampled_error;
      auto upsampled = make_renderer(RendererKind::kUpsampled, config.fitter.render, config.fitter.model, plans)
                           ->prepare_psf(out.model, &upsampled_error);
      if (upsampled) {
        out.auto_note = "renderer = auto: the upsampled renderer (the exact one refuses this PSF: " + error + ")";
        out.kind = RendererKind::kUpsampled;
        out.prepared = std::move(upsampled);
      }
    }
  }
  // A metacal run never fits the data with this PSF, only deconvolves it (checked_reconvolution_psf
  // checks that), so a renderer that cannot take it (the exact one, an image) is no obstacle.
  if (!out.prepared && !config.metacal.enabled) throw std::runtime_error("PSF (" + what + "): " + error);
  return out;
}

namespace {

std::string number(double v) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.10g", v);
  return buf;
}

}  // namespace

std::vector<std::string> psf_differences(const PsfModel& recorded, const PsfModel& run) {
  std::vector<std::string> out;
  if (run.kind == PsfKind::kImage) return out;
  if (recorded.kind != run.kind) {
    out.push_back(std::string("PSFTYPE = '") + psf_kind_name(recorded.kind) + "' (psf_input = " +
                  psf_kind_name(run.kind) + ")");
    return out;
  }
  auto compare = [&](const char* key, double a, const char* option, double b) {
    if (!(std::abs(a - b) <= 1e-9 * std::max(std::abs(a), std::abs(b))))
      out.push_back(std::string(key) + " = " + number(a) + " (" + option + " = " + number(b) + ")");
  };
  if (run.kind == PsfKind::kMoffat) {
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

std::vector<std::string> psf_options_set(const app::RunConfig& config) {
  static const char* const kPsfKeys[] = {"psf_input",          "psf_beta",         "psf_fwhm",  "psf_e1",
                                         "psf_e2",             "psf_truncation",   "airy_lambda_over_d",
                                         "airy_obscuration",   "psf_image",        "psf_upsampling",
                                         "psf_pixel_integrated"};
  std::vector<std::string> set;
  for (const char* key : kPsfKeys)
    if (config.explicitly_set.contains(key)) set.emplace_back(key);
  return set;
}

bool sets_psf_options(const app::RunConfig& config) { return !psf_options_set(config).empty(); }

void use_recorded_psf(const PsfModel& recorded, const std::string& where, app::RunConfig* config) {
  std::string why;
  if (!recorded.IsValid(&why))
    throw io::ConfigError(where + " records a PSF the fit cannot use (" + why +
                          "); set psf_input and its options to choose the PSF");
  config->psf_kind = recorded.kind;
  config->psf_from_catalogue = false;
  if (recorded.kind == PsfKind::kMoffat) config->moffat = recorded.moffat;
  if (recorded.kind == PsfKind::kAiry) config->airy = recorded.airy;
}

PsfModel checked_reconvolution_psf(const PsfModel& psf, const app::RunConfig& config) {
  std::string why;
  const auto filters =
      reconvolution_filters(psf, config.metacal, MetacalImager::padded_size(config.fitter.render.stamp_size), &why);
  if (!filters) {
    // The option is named where the user set it; otherwise the PSF itself is what metacal cannot use
    // (a NaN PSF image named metacal_psf_dilation, which the run had left at its default).
    if (config.explicitly_set.count("metacal_psf_dilation"))
      throw io::ConfigError("metacal_psf_dilation = " + app::get_option(config, "metacal_psf_dilation") + ": " + why);
    std::string psf_text = "psf_input = " + app::get_option(config, "psf_input");
    if (config.psf_kind == PsfKind::kImage) psf_text += ", psf_image = " + quoted_value(config.psf_image, kQuotedPathMaxBytes);
    throw io::ConfigError("metacal = true cannot use the run's PSF (" + psf_text + "): " + why);
  }
  return filters->reconvolution();
}

}  // namespace stampede::app
