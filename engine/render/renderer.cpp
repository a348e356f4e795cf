// The renderer interface's defaults; see renderer.hpp.
#include "engine/render/renderer.hpp"

#include <stdexcept>

namespace stampede {

void Renderer::set_frame(const PixelFrame& frame) {
  if (!frame.identity())
    throw std::invalid_argument(
        "this renderer draws in its stamp's pixels only and cannot take a cutout's WCS frame: use renderer = exact");
}

}  // namespace stampede
