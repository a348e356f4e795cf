// The gnomonic (TAN) WCS; see celestial_wcs.hpp. Calabretta & Greisen (2002): the intermediate
// world coordinates (xi, eta) = CD (p - CRPIX) in degrees are the tangent plane's, whose pole is
// the reference point.
#include "io/celestial_wcs.hpp"

#include <cmath>

#include "io/fits_error.hpp"
#include "io/fits_file.hpp"

namespace stampede::io {
namespace {

constexpr double kDegree = 3.14159265358979323846 / 180.0;

}  // namespace

std::optional<std::array<double, 2>> CelestialWcs::pixel(double ra, double dec) const {
  const double a = ra * kDegree, d = dec * kDegree, a0 = crval1 * kDegree, d0 = crval2 * kDegree;
  const double cos_c = std::sin(d0) * std::sin(d) + std::cos(d0) * std::cos(d) * std::cos(a - a0);
  if (!(cos_c > 0)) return std::nullopt;
  const double xi = std::cos(d) * std::sin(a - a0) / cos_c / kDegree;
  const double eta = (std::cos(d0) * std::sin(d) - std::sin(d0) * std::cos(d) * std::cos(a - a0)) / cos_c / kDegree;
  const double det = cd[0] * cd[3] - cd[1] * cd[2];
  const double dx = (cd[3] * xi - cd[1] * eta) / det, dy = (-cd[2] * xi + cd[0] * eta) / det;
  return std::array<double, 2>{crpix1 + dx - 1, crpix2 + dy - 1};
}

std::array<double, 2> CelestialWcs::sky(double x, double y) const {
  const double px = x + 1 - crpix1, py = y + 1 - crpix2;
  const double xi = (cd[0] * px + cd[1] * py) * kDegree, eta = (cd[2] * px + cd[3] * py) * kDegree;
  const double a0 = crval1 * kDegree, d0 = crval2 * kDegree;
  const double dec = std::asin((std::sin(d0) + eta * std::cos(d0)) / std::sqrt(1 + xi * xi + eta * eta));
  double ra = a0 + std::atan2(xi, std::cos(d0) - eta * std::sin(d0));
  ra = std::fmod(ra / kDegree + 360.0, 360.0);
  return {ra, dec / kDegree};
}

std::optional<CelestialWcs> read_celestial_wcs(FitsFile& f) {
  const std::optional<std::string> t1 = f.read_key_string("CTYPE1"), t2 = f.read_key_string("CTYPE2");
  if (!t1) return std::nullopt;
  if (*t1 != "RA---TAN" || !t2 || *t2 != "DEC--TAN")
    throw FitsError(f.describe() + ": CTYPE1, CTYPE2 = '" + *t1 + "', '" + t2.value_or("") +
                    "': only the gnomonic projection without distortion terms (RA---TAN, DEC--TAN) is read");
  CelestialWcs w;
  auto need = [&](const char* key) {
    const std::optional<double> v = f.read_key_double(key);
    if (!v || !std::isfinite(*v)) throw FitsError(f.describe() + ": no finite header keyword '" + key + "' (the TAN WCS needs it)");
    return *v;
  };
  w.crval1 = need("CRVAL1"), w.crval2 = need("CRVAL2"), w.crpix1 = need("CRPIX1"), w.crpix2 = need("CRPIX2");
  if (f.read_key_double("CD1_1")) {
    w.cd = {need("CD1_1"), f.read_key_double("CD1_2").value_or(0), f.read_key_double("CD2_1").value_or(0), need("CD2_2")};
  } else {
    w.cd = {need("CDELT1"), 0, 0, need("CDELT2")};
  }
  const double det = w.cd[0] * w.cd[3] - w.cd[1] * w.cd[2];
  if (!(std::abs(det) > 0) || !std::isfinite(det)) throw FitsError(f.describe() + ": the WCS CD matrix is singular");
  return w;
}

}  // namespace stampede::io
