// Makes the fitter's renderer from the `renderer` option: the one place that knows every
// renderer kind (a new renderer adds a kind, its name and a case here).
#pragma once

#include <memory>
#include <string_view>

#include "engine/model/galaxy_model.hpp"
#include "engine/render/fft_plans.hpp"
#include "engine/render/render_options.hpp"
#include "engine/render/renderer.hpp"

namespace stampede {

enum class RendererKind {
  kUpsampled,  // render/upsampled_renderer: the paper's upsampled grid, FFT convolution
  kExact,      // render/exact_renderer: the continuous transform at data resolution
  // The default: exact wherever it can take the PSF, upsampled where it cannot (the run's PSF is
  // resolved in app/psf_setup); make_renderer makes the exact renderer for it.
  kAuto,
};
// "upsampled", "exact", "auto".
const char* renderer_kind_name(RendererKind kind);
// Case-insensitive inverse of renderer_kind_name; false for anything else.
bool parse_renderer_kind(std::string_view name, RendererKind* out);
// The allowed names, comma-separated, for messages and help ("auto, exact, upsampled").
const char* renderer_kind_names();

// A renderer without a PSF (set_psf before rendering). `plans` are the calling thread's and must
// outlive the renderer. Throws std::invalid_argument for invalid options.
std::unique_ptr<Renderer> make_renderer(RendererKind kind, const RenderOptions& render, const ModelOptions& model,
                                        FftPlanCache& plans);

}  // namespace stampede
