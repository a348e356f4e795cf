// An image's celestial WCS (the gnomonic projection, CTYPE RA---TAN / DEC--TAN, with CRVAL, CRPIX
// and a CD matrix or CDELT), read from its header: sky positions (a star catalogue's ra, dec) to
// its pixels. Other projections and distortion terms (TPV, SIP) are refused by name.
#pragma once
#include <array>
#include <optional>
#include <string>

namespace stampede::io {

class FitsFile;

struct CelestialWcs {
  double crval1 = 0, crval2 = 0;  // degrees: the reference point's ra, dec
  double crpix1 = 0, crpix2 = 0;  // its FITS 1-based pixel
  std::array<double, 4> cd{};     // degrees per pixel, row-major (CD1_1, CD1_2, CD2_1, CD2_2)

  // The 0-based pixel (x, y) of (ra, dec) in degrees; nullopt on the far side of the projection.
  std::optional<std::array<double, 2>> pixel(double ra, double dec) const;
  // The inverse: (ra, dec) in degrees of the 0-based pixel (x, y).
  std::array<double, 2> sky(double x, double y) const;
};

// The current HDU's celestial WCS: nullopt without CTYPE1; a FitsError naming the file, HDU and key
// for one this reader cannot use (another projection, a singular matrix, a missing key).
std::optional<CelestialWcs> read_celestial_wcs(FitsFile& f);

}  // namespace stampede::io
