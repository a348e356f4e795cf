// What a run over a MEDS tile chooses beyond the fitter (ini keys meds_*; README "Multi-epoch
// survey input"): the model, which cutouts, which pixels are masked, the PSFs' place and the
// output fluxes' zero point.
#pragma once

#include <cstdint>
#include <string>

namespace stampede::io {

// `bd`: the co-elliptical bulge + disc; `bord`: a pure bulge and a pure disc fitted each, the
// better likelihood kept (DES Y1's im3shape).
enum class MedsModel { kBulgeDisc, kBulgeOrDisc };

// Where each cutout's PSF comes from: the tile's `psf` cutouts, its source image's PSFEx model
// (image_info psf_path), or the run's PSF options (one analytic PSF in every cutout's pixels, for
// simulations); auto: the cutouts when the tile has them, else PSFEx.
enum class MedsPsfSource { kAuto, kPsfex, kCutouts, kOptions };

struct MedsOptions {
  MedsModel model = MedsModel::kBulgeDisc;
  MedsPsfSource psf = MedsPsfSource::kAuto;
  bool fit_coadd = false;  // fit cutout 0 (the coadd) alone instead of the single epochs
  std::uint32_t bmask_bits = 0xffffffffu;  // a pixel with any of these bmask bits set is masked
  bool uberseg = true;                     // mask pixels nearest another object in the seg map
  double min_unmasked_fraction = 0.5;      // of the usable cutouts' pixels; below it the row is flagged
  double magzp_ref = 30;                   // the output fluxes' zero point
  std::string psf_dir;                     // where image_info's psf_path is relative to; "" = the tile's directory
};

}  // namespace stampede::io
