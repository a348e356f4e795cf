// The run's shared PSF from its configuration (psf_input = moffat, airy or image), for the
// commands that fit with one PSF for every object (`fit`, `calibrate build`).
#pragma once

#include <cmath>
#include <memory>
#include <string>
#include <vector>

#include "engine/model/psf_model.hpp"
#include "engine/render/fft_plans.hpp"
#include "engine/render/renderer.hpp"
#include "engine/render/renderer_factory.hpp"
#include "app/run_config.hpp"

namespace stampede::app {

struct SharedPsf {
  PsfModel model;
  std::shared_ptr<const PreparedPsf> prepared;  // by `kind`
  // The run's renderer kind, renderer = auto resolved: exact when the exact renderer takes the
  // PSF, else upsampled (auto_note then says why). Fitters of this PSF use this kind.
  RendererKind kind = RendererKind::kAuto;
  std::string auto_note;
  double e1 = NAN, e2 = NAN, fwhm = NAN;  // as written to the output rows (NaN: unknown, image PSF)
};

// Reads psf_image when psf_input = image. Throws (naming psf_input, or the image file) when the PSF
// cannot be built. Not for psf_input = moffat_catalog.
// A renderer of the run's kind and options prepares it, with `plans`.
SharedPsf build_shared_psf(const app::RunConfig& config, FftPlanCache& plans);
// `model` prepared by a renderer of config's kind and options, for a PSF the caller made (the Python
// module's PSF arrays). Throws std::runtime_error "PSF (WHAT): why" when it cannot be prepared.
SharedPsf prepare_shared_psf(const PsfModel& model, const app::RunConfig& config, FftPlanCache& plans,
                             const std::string& what);

// Where a PSF recorded in an input's header (io::read_psf_keys) differs from the run's analytic
// PSF: one "KEY = recorded (option = run's)" per differing parameter, in header order; empty when
// they agree to 1e-9 relative. A run with an image PSF has nothing to compare: empty.
std::vector<std::string> psf_differences(const PsfModel& recorded, const PsfModel& run);

// Whether the run chooses its PSF: any of psf_input, the psf_* and airy_* keys, psf_image,
// psf_upsampling or psf_pixel_integrated explicitly set. A run that sets none fits a grid whose
// header records a PSF with that PSF (use_recorded_psf) rather than with the defaults.
bool sets_psf_options(const app::RunConfig& config);
// Those of the keys above that the run sets, in that order.
std::vector<std::string> psf_options_set(const app::RunConfig& config);
// config's PSF replaced by `recorded`, an analytic PSF as io::read_psf_keys returns it, so the effective
// options (output header, fingerprint) record the PSF the fit used. Throws io::ConfigError naming
// `where` (the file and HDU) when the recorded PSF is not a valid one.
void use_recorded_psf(const PsfModel& recorded, const std::string& where, app::RunConfig* config);

// The reconvolution PSF a metacal run uses with `psf` (config.metacal), checked by building the
// filters once: throws io::ConfigError naming metacal_psf_dilation when metacal cannot use it (a Γ
// not wider than the sheared PSF), so a run fails before fitting rather than flagging every row.
PsfModel checked_reconvolution_psf(const PsfModel& psf, const app::RunConfig& config);
}  // namespace stampede::app
