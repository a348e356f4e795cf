// One image of an object as metacalibration takes it: a MEDS cutout, or a grid or catalogue stamp
// (one epoch whose frame is its pixel grid). Unlike a fit's Observation it carries the PSF
// unprepared: metacal deconvolves it and fits the images with its own reconvolution PSF.
#pragma once

#include <span>

#include "engine/fit/observation.hpp"
#include "engine/model/pixel_frame.hpp"
#include "engine/model/psf_model.hpp"

namespace stampede {

struct MetacalEpoch {
  std::span<const double> pixels;  // box_size^2, row-major
  std::span<const double> weight;  // per pixel, 0 masks; empty: every pixel noise_sigma's (a stamp)
  int box_size = 0;
  PixelFrame frame;
  const PsfModel* psf = nullptr;  // the epoch's PSF in its pixels
  double flux_scale = 1;          // data = flux_scale x model
  int band = 0;                   // multi-band objects: the epoch's band
  // A stamp's weights may be a mask on noise_sigma instead (observation.hpp); cutouts' are
  // inverse variances.
  WeightKind weight_kind = WeightKind::kInverseVariance;
};

}  // namespace stampede
