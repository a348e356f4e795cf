// Render option validation; see render_options.hpp.
#include "engine/render/render_options.hpp"

#include <sstream>

namespace stampede {

bool ExactRenderOptions::IsValid(std::string* why) const {
  std::ostringstream msg;
  if (!(psf_tolerance > 0 && psf_tolerance < 1e-2))
    msg << "exact_psf_tolerance = " << psf_tolerance << ": must be in (0, 1e-2)";
  else if (period < 0 || period > 4096)
    msg << "exact_period = " << period << ": must be 0 (the rule) or a grid size up to 4096 pixels";
  else if (wrap_rings < 0 || wrap_rings > 64)
    msg << "exact_wrap_rings = " << wrap_rings << ": must be 0 (no wrap correction) to 64";
  else if (wrap_nodes < 2 || wrap_nodes > 64)
    msg << "exact_wrap_nodes = " << wrap_nodes << ": must be 2 to 64";
  else if (!(surrogate_psf_tolerance > 0 && surrogate_psf_tolerance < 1e-2))
    msg << "surrogate_psf_tolerance = " << surrogate_psf_tolerance << ": must be in (0, 1e-2)";
  else if (surrogate_period < 0 || surrogate_period > 4096)
    msg << "surrogate_period = " << surrogate_period << ": must be 0 (the rule) or a grid size up to 4096 pixels";
  else if (surrogate_wrap_rings < 0 || surrogate_wrap_rings > 64)
    msg << "surrogate_wrap_rings = " << surrogate_wrap_rings << ": must be 0 (no wrap correction) to 64";
  else if (surrogate_wrap_nodes < 2 || surrogate_wrap_nodes > 64)
    msg << "surrogate_wrap_nodes = " << surrogate_wrap_nodes << ": must be 2 to 64";
  if (msg.str().empty()) return true;
  if (why) *why = msg.str();
  return false;
}

bool RenderOptions::IsValid(std::string* why) const {
  std::ostringstream msg;
  if (stamp_size < 3 || stamp_size > 4096)
    msg << "stamp_size = " << stamp_size << ": must be in [3, 4096]";
  else if (upsampling < 1 || upsampling > 32)
    msg << "upsampling = " << upsampling << ": must be an integer in [1, 32]";
  else if (n_central_pixels_to_upsample < 0 || n_central_pixels_to_upsample > upsampling * stamp_size)
    msg << "n_central_pixels_to_upsample = " << n_central_pixels_to_upsample
        << ": must be in [0, upsampling * stamp_size]";
  else if (n_central_pixel_upsampling < 1 || n_central_pixel_upsampling > 64)
    msg << "n_central_pixel_upsampling = " << n_central_pixel_upsampling << ": must be in [1, 64]";
  else if (padding < 0 || padding > 4 * stamp_size)
    msg << "padding = " << padding << ": must be in [0, 4 * stamp_size]";
  else if (static_cast<long>(upsampling) * (stamp_size + 2L * padding) > 8192)
    msg << "upsampling * (stamp_size + 2 padding) = " << upsampling * (stamp_size + 2 * padding)
        << ": model grid larger than 8192 sub-pixels per side";
  else if (!kernels::profile_kernels_for(simd))
    msg << "simd = " << kernels::isa_name(simd) << ": this build or CPU does not support it";
  if (msg.str().empty()) return true;
  if (why) *why = msg.str();
  return false;
}

}  // namespace stampede
