// The seam between the fitter and whatever draws model images: parameters in, model image and
// Jacobian images at data resolution out, plus everything else the fitter asks of a model (the
// PSF, the effective parameters, the component fluxes). Renderers are made by
// render/renderer_factory from the `renderer` option and must pass
// tests/engine/render/renderer_contract_test.cpp.
//
// PSFs: a renderer turns a PsfModel into its own prepared form (an FFT kernel, a tabulated
// transform...) with prepare_psf, once per distinct PSF; the result is immutable and shared
// read-only by every thread's renderer of the same kind and options (render/psf_cache keeps them
// for per-object PSFs). set_psf then swaps it in without allocating.
#pragma once

#include <memory>
#include <span>
#include <string>

#include "engine/model/parameters.hpp"
#include "engine/model/pixel_frame.hpp"
#include "engine/model/psf_model.hpp"

namespace stampede {

enum class RenderStatus {
  kOk,
  kInvalidModel,  // no model exists for these parameters (non-finite, |e| >= 1 after offsets)
  kNoPsf,         // no PSF has been set (set_psf)
};

// A PSF as one renderer kind prepared it. What every kind provides is what the fitter needs of the
// PSF besides the images: its adaptive second moments (for the starting point's size correction).
class PreparedPsf {
 public:
  virtual ~PreparedPsf() = default;
  // Adaptive second moments of the pixel-convolved PSF, pixels^2.
  virtual double xx() const = 0;
  virtual double xy() const = 0;
  virtual double yy() const = 0;
};

class Renderer {
 public:
  virtual ~Renderer() = default;
  virtual int stamp_size() const = 0;

  // This renderer kind's form of `psf` for its options; null, with *error, when it cannot be
  // built (an invalid or unnormalisable PSF). Uses this renderer's per-thread scratch only.
  virtual std::shared_ptr<const PreparedPsf> prepare_psf(const PsfModel& psf, std::string* error) = 0;
  // Swaps the PSF for the following renders. Throws std::invalid_argument for a PSF another kind
  // or another grid prepared. Allocates nothing.
  virtual void set_psf(std::shared_ptr<const PreparedPsf> psf) = 0;
  // The frame the model's parameters live in (model/pixel_frame.hpp) for the following renders: x0,
  // y0 become (u0, v0), the shape is (u, v)'s, and d/dx0, d/dy0 become d/du0, d/dv0; the surrogate
  // follows it. The identity (the default) is the stamp's own pixels. A renderer that draws in its
  // stamp's pixels only (takes_frames() false) takes the identity and throws std::invalid_argument
  // for any other frame, naming itself: a joint fit over cutouts' WCS needs one that takes frames.
  virtual bool takes_frames() const { return false; }
  virtual void set_frame(const PixelFrame& frame);

  // model: stamp_size^2 pixels, flux per pixel.
  virtual RenderStatus render(const ParamVector& p, std::span<double> model) = 0;

  // model as above; jacobian[k] (stamp_size^2 each) = d model / d free[k].
  virtual RenderStatus render_with_jacobian(const ParamVector& p, std::span<const Param> free, std::span<double> model,
                                            std::span<double* const> jacobian) = 0;

  // The two component images per unit amplitude, stamp_size^2 each: the model is
  // A_b bulge + A_d disc (p's amplitudes are not used). What a fit that solves the amplitudes
  // linearly draws at a trial shape.
  virtual RenderStatus render_components(const ParamVector& p, std::span<double> bulge, std::span<double> disc) = 0;

  // The values p is drawn with: p with e1, e2 and the radius replaced by their effective
  // (mirrored, softened) values. False when no model exists for p (*out is then still filled).
  virtual bool effective_params(const ParamVector& p, ParamVector* out) const = 0;
  // Analytic total flux of each component at p (before the PSF and the stamp's edge).
  virtual void component_fluxes(const ParamVector& p, double* bulge, double* disc) const = 0;

  // A cheaper approximation of the same model for a fit to iterate on before its iterations with
  // this renderer (same parameters, frame and PSF, set with this renderer's); null when there is
  // none, or none for the current PSF.
  virtual Renderer* surrogate() { return nullptr; }
};

}  // namespace stampede
