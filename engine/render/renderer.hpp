// The narrow interface between the fitter and whatever draws model images: parameters in, model
// image and Jacobian images at data resolution out. A faster renderer can be swapped in behind it
// and compared with the reference one.
#pragma once

#include <span>

#include "engine/model/parameters.hpp"

namespace stampede {

enum class RenderStatus {
  kOk,
  kInvalidModel,  // no model exists for these parameters (non-finite, |e| >= 1 after offsets)
};

class Renderer {
 public:
  virtual ~Renderer() = default;
  virtual int stamp_size() const = 0;

  // model: stamp_size^2 pixels, flux per pixel.
  virtual RenderStatus render(const ParamVector& p, std::span<double> model) = 0;

  // model as above; jacobian[k] (stamp_size^2 each) = d model / d free[k].
  virtual RenderStatus render_with_jacobian(const ParamVector& p, std::span<const Param> free, std::span<double> model,
                                            std::span<double* const> jacobian) = 0;
};

}  // namespace stampede
