// Reads a bright-star mask catalogue (`stampede metadetect --star-mask STARS.fits`): the first
// binary table HDU (or the HDU named `extname`: `--star-mask-hdu`, an image's own stars), one row
// per star with columns x, y (FITS 1-based pixels of the image, as Source Extractor's X_IMAGE,
// Y_IMAGE) and radius (pixels), or ra, dec (degrees) and radius_arcsec, placed on each image by
// its celestial WCS (io/celestial_wcs). Each star becomes a StarDisc of the image's 0-based pixels
// whose radius is the row's plus `margin` pixels. Every failure throws FitsError naming the file,
// the HDU, the column and the row.
#pragma once
#include <string>
#include <vector>

#include "engine/metadetect/star_disc.hpp"
#include "io/celestial_wcs.hpp"

namespace stampede::io {

struct StarCatalogue {
  std::string where;  // the file and HDU, for messages
  bool sky = false;   // ra, dec, radius_arcsec; else x, y, radius
  // pixel: 0-based x, y and the radius with the margin; sky: ra, dec (degrees) in x, y and the
  // radius in arcsec.
  std::vector<StarDisc> stars;
  double margin = 0;  // pixels

  // The discs in the pixels of an image (`image` names it in messages) of `scale` arcsec per pixel
  // and celestial WCS `wcs` (null: none; a sky catalogue then throws ConfigError naming both). A
  // star on the far side of the projection reaches no pixel and is left out.
  std::vector<StarDisc> discs(const CelestialWcs* wcs, double scale, const std::string& image) const;
};

StarCatalogue read_star_table(const std::string& path, double margin, const std::string& extname = "");

// A pixel catalogue's discs (a sky one throws ConfigError: it needs an image's WCS).
std::vector<StarDisc> read_star_catalogue(const std::string& path, double margin, const std::string& extname = "");

}  // namespace stampede::io
