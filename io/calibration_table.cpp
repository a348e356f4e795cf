// Calibration file I/O; see calibration_table.hpp.
#include "io/calibration_table.hpp"

#include <cmath>
#include <cstdio>
#include <sstream>
#include <utility>

#include "engine/common/quoted_value.hpp"
#include "io/fits_file.hpp"
#include "io/psf_keys.hpp"

namespace stampede::io {
namespace {

constexpr long long kVersion = 1;

std::string join(const std::vector<double>& v) {
  std::string s;
  char buf[32];
  for (std::size_t i = 0; i < v.size(); ++i) {
    std::snprintf(buf, sizeof buf, "%.17g", v[i]);
    if (i) s += ',';
    s += buf;
  }
  return s;
}

std::vector<double> split(FitsFile& f, const std::string& key) {
  const std::string text = f.key_string(key);
  std::vector<double> out;
  std::stringstream ss(text);
  std::string item;
  while (std::getline(ss, item, ',')) {
    try {
      std::size_t used = 0;
      out.push_back(std::stod(item, &used));
      if (used != item.size()) throw std::invalid_argument(item);
    } catch (const std::exception&) {
      f.move_to(0);
      throw FitsError(f.describe() + ": header keyword '" + key + "' = " + quoted_value(text) +
                               " is not a comma-separated list of numbers");
    }
  }
  return out;
}

// A header integer held as an int: a wider value had wrapped (NREAL = 2^32 + 16 read as 16).
int key_int(FitsFile& f, const std::string& key) {
  const long long v = f.key_long(key);
  if (!std::in_range<int>(v))
    throw FitsError(f.describe() + ": header keyword '" + key + "' = " + std::to_string(v) + " is out of range");
  return static_cast<int>(v);
}

// An integer column's value (stored as a double by the writer) as an int: a NaN, fractional or
// out-of-range one is an error naming the row, not a float-to-int conversion (undefined).
int column_int(FitsFile& f, const char* column, std::size_t row, double v) {
  if (!(v >= -2147483648.0 && v <= 2147483647.0 && v == std::trunc(v))) {
    char buf[32];
    std::snprintf(buf, sizeof buf, "%.17g", v);
    throw FitsError(f.describe() + ": row " + std::to_string(row + 1) + ": column '" + column + "' = " + buf +
                    " is not an integer");
  }
  return static_cast<int>(v);
}

// The axis column: 0 (e along e1) or 1 (along e2), as written.
BiasAxis column_axis(FitsFile& f, std::size_t row, double v) {
  const int axis = column_int(f, "axis", row, v);
  if (axis != 0 && axis != 1)
    throw FitsError(f.describe() + ": row " + std::to_string(row + 1) + ": column 'axis' = " + std::to_string(axis) +
                    " is neither 0 (e1) nor 1 (e2)");
  return axis == 0 ? BiasAxis::kE1 : BiasAxis::kE2;
}

FitsFile::OutputColumn column(const std::string& name, bool integer = false) { return {name, integer, {}}; }

}  // namespace

void write_calibration_table(const std::string& path, const CalibrationTable& t, bool overwrite) {
  FitsFile f = FitsFile::create(path, overwrite);
  f.write_empty_image();
  const CalibrationGridOptions& g = t.grid;
  f.write_key("CALIBVER", kVersion, "stampede noise-bias calibration, format version");
  f.write_key("SNRREF", g.snr, "reference S/N of the simulations");
  f.write_key("NOISESIG", g.noise_sigma, "noise sigma per pixel of the simulations");
  f.write_key("NREAL", static_cast<long long>(g.realisations), "noise pairs (n, -n) per grid point");
  f.write_key("ESTEPS", static_cast<long long>(g.e_steps), "e_true steps over [-EMAX, EMAX]");
  f.write_key("EMAX", g.e_max, "largest |e_true|");
  f.write_key("STAMPSZ", static_cast<long long>(g.stamp_size), "stamp size, pixels");
  f.write_key("RRATIO", g.bulge_radius_ratio, "bulge / disc half-light radius");
  f.write_key("SEED", static_cast<long long>(g.seed & 0x7fffffffffffffffull), "noise seed");
  f.write_key("RADII", join(g.radii), "disc half-light radii r_d of the grid, pixels");
  f.write_key("BFRACS", join(g.bulge_fractions), "bulge flux fractions F of the grid");
  write_psf_keys(f, g.psf);
  for (std::size_t i = 0; i < t.config.size(); ++i) {
    char key[32];
    std::snprintf(key, sizeof key, "CFG%04zu", i + 1);
    f.write_key(key, t.config[i].first + " = " + t.config[i].second, "fit configuration of the calibration run");
  }

  std::vector<FitsFile::OutputColumn> points = {
      column("point", true), column("radius"),   column("bulge_fraction"), column("axis", true),
      column("e_true"),      column("bias1"),    column("bias1_err"),      column("bias2"),
      column("bias2_err"),   column("pairs_used", true), column("pairs_failed", true)};
  for (std::size_t i = 0; i < t.points.size(); ++i) {
    const CalibrationPoint& p = t.points[i];
    const PointBias& b = t.biases.at(i);
    const double row[] = {static_cast<double>(p.index), p.radius, p.bulge_fraction, static_cast<double>(p.axis),
                          p.e_true, b.bias[0], b.error[0], b.bias[1], b.error[1],
                          static_cast<double>(b.pairs_used), static_cast<double>(b.pairs_failed)};
    for (std::size_t c = 0; c < points.size(); ++c) points[c].values.push_back(row[c]);
  }
  f.write_table("POINTS", points);

  std::vector<FitsFile::OutputColumn> curves = {
      column("radius"), column("bulge_fraction"), column("axis", true), column("component", true),
      column("a0"),     column("a1"),             column("a2"),         column("a3"),
      column("a0_err"), column("a1_err"),         column("a2_err"),     column("a3_err"),
      column("chi2"),   column("points", true)};
  for (const BiasCurve& c : t.curves) {
    const double row[] = {c.radius, c.bulge_fraction, static_cast<double>(c.axis), static_cast<double>(c.component),
                          c.coefficients[0], c.coefficients[1], c.coefficients[2], c.coefficients[3],
                          c.errors[0], c.errors[1], c.errors[2], c.errors[3], c.chi2, static_cast<double>(c.points)};
    for (std::size_t k = 0; k < curves.size(); ++k) curves[k].values.push_back(row[k]);
  }
  f.write_table("CURVES", curves);
  f.close();
}

CalibrationTable read_calibration_table(const std::string& path) {
  FitsFile f = FitsFile::open_read(path);
  f.move_to(0);
  CalibrationTable t;
  CalibrationGridOptions& g = t.grid;
  if (f.key_long("CALIBVER") != kVersion)
    throw FitsError(f.describe() + ": CALIBVER " + std::to_string(f.key_long("CALIBVER")) +
                             " is not a calibration format this version reads (" + std::to_string(kVersion) + ")");
  g.snr = f.key_double("SNRREF");
  g.noise_sigma = f.key_double("NOISESIG");
  g.realisations = key_int(f, "NREAL");
  g.e_steps = key_int(f, "ESTEPS");
  g.e_max = f.key_double("EMAX");
  g.stamp_size = key_int(f, "STAMPSZ");
  g.bulge_radius_ratio = f.key_double("RRATIO");
  g.seed = static_cast<std::uint64_t>(f.key_long("SEED"));
  g.radii = split(f, "RADII");
  g.bulge_fractions = split(f, "BFRACS");
  g.psf = read_psf_keys(f);
  for (int i = 1;; ++i) {
    char key[32];
    std::snprintf(key, sizeof key, "CFG%04d", i);
    const auto card = f.read_key_string(key);
    if (!card) break;
    // FITS drops trailing blanks: an empty value reads back as "key =".
    const auto eq = card->find(" =");
    if (eq == std::string::npos || eq == 0)
      throw FitsError(f.describe() + ": " + key + " = " + quoted_value(*card) + " is not 'key = value'");
    std::string value = card->substr(eq + 2);
    if (!value.empty() && value[0] == ' ') value.erase(0, 1);
    t.config.emplace_back(card->substr(0, eq), value);
  }
  std::string why;
  if (!g.IsValid(&why)) throw FitsError(f.describe() + ": the grid in the header is not valid: " + why);

  f.move_to("POINTS");
  const auto point = f.read_column("point"), radius = f.read_column("radius"), fraction = f.read_column("bulge_fraction"),
             axis = f.read_column("axis"), e_true = f.read_column("e_true"), b1 = f.read_column("bias1"),
             e1 = f.read_column("bias1_err"), b2 = f.read_column("bias2"), e2 = f.read_column("bias2_err"),
             used = f.read_column("pairs_used"), failed = f.read_column("pairs_failed");
  for (std::size_t i = 0; i < point.size(); ++i) {
    CalibrationPoint p;
    p.index = column_int(f, "point", i, point[i]);
    p.radius = radius[i];
    p.bulge_fraction = fraction[i];
    p.axis = column_axis(f, i, axis[i]);
    p.e_true = e_true[i];
    t.points.push_back(p);
    PointBias b;
    b.bias[0] = b1[i];
    b.error[0] = e1[i];
    b.bias[1] = b2[i];
    b.error[1] = e2[i];
    b.pairs_used = column_int(f, "pairs_used", i, used[i]);
    b.pairs_failed = column_int(f, "pairs_failed", i, failed[i]);
    t.biases.push_back(b);
  }

  f.move_to("CURVES");
  std::vector<std::vector<double>> c;
  for (const char* name : {"radius", "bulge_fraction", "axis", "component", "a0", "a1", "a2", "a3", "a0_err", "a1_err",
                           "a2_err", "a3_err", "chi2", "points"})
    c.push_back(f.read_column(name));
  for (std::size_t i = 0; i < c[0].size(); ++i) {
    BiasCurve curve;
    curve.radius = c[0][i];
    curve.bulge_fraction = c[1][i];
    curve.axis = column_axis(f, i, c[2][i]);
    curve.component = column_int(f, "component", i, c[3][i]);
    for (int k = 0; k < 4; ++k) {
      curve.coefficients[k] = c[4 + k][i];
      curve.errors[k] = c[8 + k][i];
    }
    curve.chi2 = c[12][i];
    curve.points = column_int(f, "points", i, c[13][i]);
    t.curves.push_back(curve);
  }
  return t;
}

}  // namespace stampede::io
