// GREAT08-layout writer; see great08_writer.hpp.
#include "io/great08_writer.hpp"

#include <vector>

#include "io/fits_file.hpp"
#include "io/psf_keys.hpp"

namespace stampede::io {
namespace {

// Keywords shared by the set and truth headers (those of the GalSim sets, plus our own provenance).
void write_common_keys(FitsFile& f, const Great08SimOptions& o, const SimSet& set) {
  f.write_key("STAMPSZ", o.stamp_size, "stamp size in pixels (square)");
  f.write_key("GRIDNX", o.grid, "stamps along x (columns)");
  f.write_key("GRIDNY", o.grid, "stamps along y (rows)");
  f.write_key("NOISESIG", o.noise_free ? 0.0 : o.noise_sigma, "sigma of the Gaussian noise added (0 = none)");
  f.write_key("NOISEREF", o.noise_sigma, "sigma used to set fluxes for SNR");
  f.write_key("SNR", o.snr, "sqrt(sum I^2)/NOISEREF per galaxy");
  write_psf_keys(f, o.psf);
  f.write_key("PIXSCALE", 1.0, "pixel scale (1 unit = 1 pixel)");
  f.write_key("SIZERAT", o.size_ratio, "Rgp/Rp target (see SIZEDEF)");
  f.write_key("SIZEDEF", std::string("fwhm"), "size measure of round profiles, no pixel");
  f.write_key("GALTYPE", std::string(sim_galaxy_type_name(o.galaxy_type)), "bd | b+d | bulge | disc");
  f.write_key("ESIG", o.e_sigma, "intrinsic e sigma per component");
  f.write_key("EMAX", o.e_max, "intrinsic |e| truncation");
  f.write_key("SHEARMAX", o.shear_max, "|g_i| < SHEARMAX uniform");
  f.write_key("SEED", static_cast<long long>(o.seed & 0x7fffffffffffffffull), "master seed");
  f.write_key("NOISEFRE", std::string(o.noise_free ? "T" : "F"), "noise-free image");
  f.write_key("CENTCONV", std::string("0-based, pixel centre at integer"), "position convention");
  f.write_key("ECONV", std::string("reduced shear g=(a-b)/(a+b)"), "ellipticity convention");
  f.write_key("RINGPAIR", std::string("T"), "objects 2m,2m+1 are 90-deg rotated pairs");
  f.write_key("NOISEPR", std::string(o.noise_pairs ? "T" : "F"), "4q+2,4q+3 = 4q,4q+1 with noise negated");
  // -1: none; otherwise the set holding the same galaxies and noise under the opposite shear.
  f.write_key("SHEARPR", o.shear_pairs ? (set.index ^ 1) : -1, "set with same galaxies, noise and -g (-1 none)");
  f.write_key("SIMCODE", std::string("stampede sim great08"), "simulator");
  f.write_key("SETIDX", set.index, "set index");
  f.write_key("NOISESD", static_cast<long long>(set.noise_seed & 0x7fffffffffffffffull),
              "noise stream seed (0 = none)");
}

std::vector<FitsFile::OutputColumn> truth_columns(const SimSet& set) {
  using T = SimObjectTruth;
  struct Spec {
    const char* name;
    bool integer;
    double (*get)(const T&);
  };
  static const Spec specs[] = {
      {"index", true, [](const T& t) { return double(t.index); }},
      {"ix", true, [](const T& t) { return double(t.ix); }},
      {"iy", true, [](const T& t) { return double(t.iy); }},
      {"pair", true, [](const T& t) { return double(t.pair); }},
      {"x_centre", false, [](const T& t) { return t.x_centre; }},
      {"y_centre", false, [](const T& t) { return t.y_centre; }},
      {"x_image", false, [](const T& t) { return t.x_image; }},
      {"y_image", false, [](const T& t) { return t.y_image; }},
      {"e1_int", false, [](const T& t) { return t.e1_int; }},
      {"e2_int", false, [](const T& t) { return t.e2_int; }},
      {"g1", false, [](const T& t) { return t.g1; }},
      {"g2", false, [](const T& t) { return t.g2; }},
      {"e1_obs", false, [](const T& t) { return t.e1_obs; }},
      {"e2_obs", false, [](const T& t) { return t.e2_obs; }},
      {"hlr", false, [](const T& t) { return t.hlr; }},
      {"bulge_frac", false, [](const T& t) { return t.bulge_frac; }},
      {"flux", false, [](const T& t) { return t.flux; }},
      {"bulge_flux", false, [](const T& t) { return t.bulge_flux; }},
      {"disc_flux", false, [](const T& t) { return t.disc_flux; }},
      {"stamp_flux", false, [](const T& t) { return t.stamp_flux; }},
      {"snr", false, [](const T& t) { return t.snr; }},
      {"hlr_bulge", false, [](const T& t) { return t.hlr_bulge; }},
      {"e1_int_bulge", false, [](const T& t) { return t.e1_int_bulge; }},
      {"e2_int_bulge", false, [](const T& t) { return t.e2_int_bulge; }},
      {"bulge_dx", false, [](const T& t) { return t.bulge_dx; }},
      {"bulge_dy", false, [](const T& t) { return t.bulge_dy; }},
  };
  std::vector<FitsFile::OutputColumn> columns;
  for (const Spec& s : specs) {
    FitsFile::OutputColumn c{s.name, s.integer, {}};
    c.values.reserve(set.truth.size());
    for (const T& t : set.truth) c.values.push_back(s.get(t));
    columns.push_back(std::move(c));
  }
  return columns;
}

}  // namespace

void write_great08_set(const std::string& directory, const Great08Simulator& simulator, const SimSet& set,
                       const std::string& command_line, bool overwrite) {
  const Great08SimOptions& o = simulator.options();
  const std::string k = std::to_string(set.index);
  {
    FitsFile f = FitsFile::create(directory + "/set_" + k + ".fits", overwrite);
    f.write_image(set.width, set.width, set.image, "", FitsFile::PixelType::kFloat32);
    write_common_keys(f, o, set);
    f.close();
  }
  {
    FitsFile f = FitsFile::create(directory + "/truth_" + k + ".fits", overwrite);
    f.write_empty_image();
    write_common_keys(f, o, set);
    f.write_key("SHEAR1", set.shear1, "constant reduced shear g1 of this set");
    f.write_key("SHEAR2", set.shear2, "constant reduced shear g2 of this set");
    f.write_key("CMDLINE", command_line, "command that made this set");
    f.write_table("TRUTH", truth_columns(set));
    f.close();
  }
  {
    FitsFile f = FitsFile::create(directory + "/psf_" + k + ".fits", overwrite);
    const int s = o.stamp_size;
    const std::vector<double> psf = simulator.psf_image();
    f.write_image(s, s, psf, "", FitsFile::PixelType::kFloat32);
    double sum = 0;
    for (double v : psf) sum += v;
    f.write_key("STAMPSZ", s, "PSF image size (pixels)");
    f.write_key("PSFCEN", 0.5 * (s - 1), "PSF centre, 0-based, pixel centres at integers");
    f.write_key("PSFSUM", sum, "sum of pixels (profile flux = 1)");
    f.write_key("PIXINT", std::string("T"), "pixel-integrated");
    const int n = s * kPsfOversampling;
    f.write_image(n, n, simulator.psf_oversampled(kPsfOversampling), "PSF_NOPIX_OS", FitsFile::PixelType::kFloat32);
    f.write_key("OVERSAMP", kPsfOversampling, "fine pixels per coarse pixel (per axis)");
    f.write_key("PSFCENF", 0.5 * (n - 1), "PSF centre in fine 0-based pixel coords");
    f.write_key("PIXINT", std::string("F"), "NOT pixel-integrated");
    f.close();
  }
}

}  // namespace stampede::io
