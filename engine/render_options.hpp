// Resolution options of the model renderer (im3shape section 4.1) and the grid they imply.
#pragma once

#include <string>

#include "kernels/profile_render.hpp"

namespace stampede {

struct RenderOptions {
  int stamp_size = 39;                    // data pixels per stamp side
  int upsampling = 5;                     // U1: model sub-pixels per data pixel, per side
  int n_central_pixels_to_upsample = 3;   // N_u: side of the central block of sub-pixels integrated finely
  int n_central_pixel_upsampling = 7;     // U2: integration points per sub-pixel side in that block
  int padding = 0;                        // data pixels of model grid added on every side of the stamp

  // Message names the option (as in the ini file), its value and the constraint.
  bool IsValid(std::string* why) const;
};

// The upsampled model grid: (stamp_size + 2 padding) * upsampling sub-pixels per side.
struct GridGeometry {
  int stamp_size = 0;
  int upsampling = 1;
  int padding = 0;

  explicit GridGeometry(const RenderOptions& o) : stamp_size(o.stamp_size), upsampling(o.upsampling), padding(o.padding) {}
  int grid_size() const { return upsampling * (stamp_size + 2 * padding); }
  double step() const { return 1.0 / upsampling; }
  // Sub-pixel i's centre is at data coordinate (i + 0.5) / U1 - 0.5 - padding.
  kernels::SubpixelGrid subpixel_grid() const { return {grid_size(), 0.5 * step() - 0.5 - padding, step()}; }
  int data_offset() const { return padding * upsampling; }
  bool operator==(const GridGeometry&) const = default;
};

}  // namespace stampede
