// Writes metadetection test cells (`stampede sim cells`, engine/sim/cell_sim) as files:
//   a cell image  HDU 0 the image (float32) with the truth in its header: SCALE (arcsec/px), G1 G2
//                 (the shear), PSFTYPE PSFFWHM (arcsec) [PSFBETA], NOISESIG, SNR, SEED, CELL, NOBJ,
//                 MODEL HLR, BAND; extensions WEIGHT (1 / NOISESIG^2, float32), BMASK (zeros, int32),
//                 NOISE (an independent noise field of sigma NOISESIG, float32) and PSF (the band's
//                 pixel-integrated PSF at the image's pixel scale, odd side, centred on its middle
//                 pixel PSFCEN, float32), and with stars a table STARS (x, y FITS 1-based pixels,
//                 radius px, flux of the band);
//   a truth table HDU 0 header-only with SHEAR1 SHEAR2 and the run's settings; HDU TRUTH a row per
//                 object: cell id x y (0-based pixels of the cell image) flux hlr (arcsec) bulge_frac
//                 e1_int e2_int e1_obs e2_obs g1 g2 snr, and flux_<band> per band when there are several.
// Each file is written as PATH.partial and renamed into place: it is either complete or absent.
#pragma once

#include <span>
#include <string>
#include <vector>

#include "engine/sim/cell_sim.hpp"

namespace stampede::io {

// Band `band` of `cell`, named `band_name` ("" for a one-band run). Throws FitsError naming the
// file, or FileError when it exists and !overwrite.
void write_cell_image(const std::string& path, const CellSimulator& simulator, const SimCell& cell, int band,
                      const std::string& band_name, bool overwrite);

// One truth row: the cell and an object of it.
struct CellTruthRow {
  int cell = 0;
  CellObject object;
};
// The run's truth under the shear (g1, g2); band_names empty for one band, else one per band.
void write_cell_truth(const std::string& path, const CellSimulator& simulator, double g1, double g2,
                      std::span<const CellTruthRow> rows, const std::vector<std::string>& band_names, bool overwrite);

}  // namespace stampede::io
