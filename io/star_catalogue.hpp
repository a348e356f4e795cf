// Reads a bright-star mask catalogue (`stampede metadetect --star-mask STARS.fits`): the first
// binary table HDU (or the HDU named `extname`: `--star-mask-hdu`, an image's own stars), one row per star with columns x, y (FITS 1-based pixels of the image, as
// Source Extractor's X_IMAGE, Y_IMAGE) and radius (pixels). Each becomes a StarDisc of 0-based
// pixels whose radius is the row's plus `margin` pixels. Every failure throws FitsError naming the
// file, the HDU, the column and the row.
#pragma once
#include <string>
#include <vector>

#include "engine/metadetect/star_disc.hpp"

namespace stampede::io {

std::vector<StarDisc> read_star_catalogue(const std::string& path, double margin, const std::string& extname = "");

}  // namespace stampede::io
