// One image of an object: its pixels and inverse-variance weights, its PSF, the frame that carries
// the sky model onto its pixels, the factor between model and data flux, and its band. A grid stamp
// is one observation whose frame is the pixel grid (the identity); a MEDS object is one per usable
// cutout, of one band or several. The PSF comes in the forms its users take: a fit draws with it
// prepared for its renderer (psf), metacalibration deconvolves the model (psf_model); a caller
// sets the ones its consumer reads.
#pragma once

#include <memory>
#include <span>

#include "engine/model/pixel_frame.hpp"
#include "engine/model/psf_model.hpp"
#include "engine/render/renderer.hpp"

namespace stampede {

// What a stamp's weight array holds: inverse variances, or a mask (0 masks a pixel, any other
// value leaves it at noise_sigma's weight, unweighted when noise_sigma = 0), e.g. the image edge
// of a cutout with no weight map, so a masked stamp follows the same weighting rules as a whole one.
enum class WeightKind { kInverseVariance, kMask };

// pixels and weight: box_size^2; an empty weight is noise_sigma's (a single stamp only).
struct Observation {
  std::span<const double> pixels{};  // box_size^2, row-major (rows slow)
  std::span<const double> weight{};  // inverse variance per pixel; 0 masks
  int box_size = 0;
  PixelFrame frame{};
  // The PSF prepared by a renderer of the fitter's options at box_size (ObjectFitter::renderer_for):
  // what ObjectFitter and Fitter draw with.
  std::shared_ptr<const PreparedPsf> psf{};
  double flux_scale = 1;  // data = flux_scale x model (a zero point's factor)
  int band = 0;           // the band whose amplitudes it sees (object_fitter)
  // A single stamp's weights may be a mask instead (a grid stamp; joint fits take inverse variances).
  WeightKind weight_kind = WeightKind::kInverseVariance;
  // The PSF in the image's pixels, not owned: what MetacalFitter deconvolves and reconvolves.
  const PsfModel* psf_model = nullptr;
};

}  // namespace stampede
