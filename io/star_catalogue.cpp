// The bright-star mask catalogue's reader; see star_catalogue.hpp.
#include "io/star_catalogue.hpp"

#include <cmath>
#include <sstream>

#include "io/fits_error.hpp"
#include "io/fits_file.hpp"

namespace stampede::io {

std::vector<StarDisc> read_star_catalogue(const std::string& path, double margin, const std::string& extname) {
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
  for (const char* c : {"x", "y", "radius"})
    if (!f.has_column(c))
      throw FitsError(f.describe() + ": no column '" + c + "' (a star mask catalogue has columns x, y, radius: "
                      "FITS 1-based pixels and pixels)");
  const std::vector<double> x = f.read_column("x"), y = f.read_column("y"), r = f.read_column("radius");
  std::vector<StarDisc> out;
  out.reserve(x.size());
  for (std::size_t i = 0; i < x.size(); ++i) {
    if (!std::isfinite(x[i]) || !std::isfinite(y[i]) || !(r[i] > 0) || !std::isfinite(r[i])) {
      std::ostringstream m;
      m << f.describe() << ": row " << i + 1 << " has x = " << x[i] << ", y = " << y[i] << ", radius = " << r[i]
        << ": positions must be finite and the radius positive";
      throw FitsError(m.str());
    }
    out.push_back({x[i] - 1, y[i] - 1, r[i] + margin});
  }
  return out;
}

}  // namespace stampede::io
