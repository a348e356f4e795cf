// The bright-star mask catalogue's reader; see star_catalogue.hpp.
#include "io/star_catalogue.hpp"

#include <cmath>
#include <sstream>

#include "io/config_error.hpp"
#include "io/fits_error.hpp"
#include "io/fits_file.hpp"

namespace stampede::io {

StarCatalogue read_star_table(const std::string& path, double margin, const std::string& extname) {
  FitsFile f = FitsFile::open_read(path);
  bool table = false;
  if (!extname.empty()) {
    if (!f.move_to_if_present(extname)) throw FitsError(path + ": no HDU '" + extname + "' (its star mask table)");
    table = f.hdu_kind() == FitsFile::HduKind::kTable;
    if (!table) throw FitsError(f.describe() + ": not a table (a star mask table has columns x, y, radius)");
  }
  for (int h = 0; h < f.hdu_count() && !table; ++h) {
    f.move_to(h);
    table = f.hdu_kind() == FitsFile::HduKind::kTable;
  }
  if (!table) throw FitsError(path + ": no binary table (a star mask catalogue has columns x, y, radius)");
  StarCatalogue out;
  out.where = f.describe();
  out.margin = margin;
  out.sky = !f.has_column("x") && f.has_column("ra");
  const char* const pixel[] = {"x", "y", "radius"};
  const char* const sky[] = {"ra", "dec", "radius_arcsec"};
  const char* const* names = out.sky ? sky : pixel;
  for (int c = 0; c < 3; ++c)
    if (!f.has_column(names[c]))
      throw FitsError(f.describe() + ": no column '" + names[c] + "' (a star mask catalogue has columns x, y, radius: "
                      "FITS 1-based pixels and pixels; or ra, dec, radius_arcsec: degrees and arcsec)");
  const std::vector<double> x = f.read_column(names[0]), y = f.read_column(names[1]), r = f.read_column(names[2]);
  out.stars.reserve(x.size());
  for (std::size_t i = 0; i < x.size(); ++i) {
    const bool bad_sky = out.sky && !(std::abs(y[i]) <= 90);
    if (!std::isfinite(x[i]) || !std::isfinite(y[i]) || !(r[i] > 0) || !std::isfinite(r[i]) || bad_sky) {
      std::ostringstream m;
      m << f.describe() << ": row " << i + 1 << " has " << names[0] << " = " << x[i] << ", " << names[1] << " = " << y[i]
        << ", " << names[2] << " = " << r[i]
        << (out.sky ? ": positions must be finite, |dec| <= 90 and the radius positive"
                    : ": positions must be finite and the radius positive");
      throw FitsError(m.str());
    }
    out.stars.push_back(out.sky ? StarDisc{x[i], y[i], r[i]} : StarDisc{x[i] - 1, y[i] - 1, r[i] + margin});
  }
  return out;
}

std::vector<StarDisc> StarCatalogue::discs(const CelestialWcs* wcs, double scale, const std::string& image) const {
  if (!sky) return stars;
  if (!wcs)
    throw ConfigError(where + " places its stars by ra, dec: " + image +
                      " has no celestial WCS (CTYPE1/2 RA---TAN, DEC--TAN with CRVAL, CRPIX and CD) to place them by");
  std::vector<StarDisc> out;
  out.reserve(stars.size());
  for (const StarDisc& s : stars)
    if (const auto p = wcs->pixel(s.x, s.y)) out.push_back({(*p)[0], (*p)[1], s.radius / scale + margin});
  return out;
}

std::vector<StarDisc> read_star_catalogue(const std::string& path, double margin, const std::string& extname) {
  return read_star_table(path, margin, extname).discs(nullptr, 0, "");
}

}  // namespace stampede::io
