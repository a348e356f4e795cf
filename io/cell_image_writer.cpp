// Metadetection test cells as files; see cell_image_writer.hpp.
#include "io/cell_image_writer.hpp"

#include <filesystem>
#include <functional>

#include "io/durable_file.hpp"
#include "io/fits_file.hpp"
#include "io/output_check.hpp"

namespace stampede::io {

namespace {

// The settings every file of a run carries.
void write_settings(FitsFile& f, const CellSimulator& simulator) {
  const CellSimOptions& o = simulator.options();
  f.write_key("SCALE", o.pixel_scale, "pixel scale, arcsec per pixel");
  f.write_key("CELLSIZE", o.size, "cell side, pixels");
  f.write_key("BUFFER", o.buffer, "edge buffer, pixels");
  f.write_key("LAYOUT", std::string(cell_layout_name(o.layout)), "object layout: grid or random");
  f.write_key("REFPOS", o.reference_positions ? 1LL : 0LL, "1: positions as the reference shear test draws them");
  if (o.layout == CellLayout::kGrid) {
    f.write_key("GRID", o.grid, "objects per side");
  } else {
    f.write_key("DENSITY", o.density, "mean objects per arcmin^2");
  }
  f.write_key("MODEL", std::string(cell_galaxy_model_name(o.model)), "galaxies: exp or bd (bulge + disc)");
  f.write_key("HLR", o.hlr, "half-light radius sqrt(ab), arcsec");
  f.write_key("SHAPENOI", o.shape_noise, "intrinsic e sigma per component");
  f.write_key("SNR", o.snr, "S/N of the reference galaxy over all bands");
  f.write_key("NOISEFRE", o.noise_free ? 1LL : 0LL, "1: noise sigma 1e-6 of the S/N's");
  f.write_key("SEED", static_cast<long long>(o.seed), "random seed");
  f.write_key("ROTATED", static_cast<long long>(o.rotate ? 1 : 0), "1: the scene turned by 90 degrees");
}

void write_partial_then_rename(const std::string& path, bool overwrite, const std::function<void(FitsFile&)>& body) {
  refuse_to_replace(path, overwrite);
  const std::string partial = path + ".partial";
  {
    FitsFile f = FitsFile::create(partial, true);
    body(f);
    f.close();
  }
  std::filesystem::rename(partial, path);
}

}  // namespace

void write_cell_image(const std::string& path, const CellSimulator& simulator, const SimCell& cell, int band,
                      const std::string& band_name, bool overwrite) {
  const CellSimOptions& o = simulator.options();
  const CellBand& b = simulator.bands().at(static_cast<std::size_t>(band));
  const CellBandImage& images = cell.bands.at(static_cast<std::size_t>(band));
  const long n = o.size;
  write_partial_then_rename(path, overwrite, [&](FitsFile& f) {
    f.write_image(n, n, images.image, "", FitsFile::PixelType::kFloat32);
    write_settings(f, simulator);
    f.write_key("CELL", cell.index, "cell index");
    f.write_key("NOBJ", static_cast<long long>(cell.objects.size()), "galaxies in this cell");
    f.write_key("G1", cell.g1, "shear g1 (reduced) of every galaxy");
    f.write_key("G2", cell.g2, "shear g2 (reduced)");
    f.write_key("PSFTYPE", std::string(cell_psf_kind_name(o.psf)), "PSF profile: gauss or moffat");
    f.write_key("PSFFWHM", b.psf_fwhm * o.pixel_scale, "PSF FWHM, arcsec");
    if (o.psf == CellPsfKind::kMoffat) f.write_key("PSFBETA", o.psf_beta, "Moffat beta");
    f.write_key("PSFE1", 0.0, "PSF e1");
    f.write_key("PSFE2", 0.0, "PSF e2");
    f.write_key("NOISESIG", b.noise_sigma, "white noise sigma per pixel");
    f.write_key("FLUXSCAL", b.flux_scale, "this band's flux over the first band's");
    if (!band_name.empty()) {
      f.write_key("BAND", band_name, "band name");
      f.write_key("IBAND", band, "band index, 0-based");
    }
    const std::vector<double> weight(images.image.size(), 1.0 / (b.noise_sigma * b.noise_sigma));
    f.write_image(n, n, weight, "WEIGHT", FitsFile::PixelType::kFloat32);
    f.write_key("BUNIT", std::string("1/NOISESIG^2"), "inverse variance");
    f.write_image(n, n, cell.bmask(static_cast<int>(n)), "BMASK", FitsFile::PixelType::kInt32);
    f.write_image(n, n, images.noise, "NOISE", FitsFile::PixelType::kFloat32);
    f.write_key("NOISESIG", b.noise_sigma, "sigma of this noise field");
    const long p = o.psf_size;
    f.write_image(p, p, b.psf, "PSF", FitsFile::PixelType::kFloat32);
    f.write_key("SCALE", o.pixel_scale, "pixel scale, arcsec per pixel");
    f.write_key("PSFCEN", static_cast<double>(p / 2), "PSF centre, 0-based, pixel centres at integers");
    f.write_key("PIXINT", std::string("T"), "pixel-integrated");
    // Its stars, for `metadetect --star-mask-hdu STARS` (x, y FITS 1-based, as a star catalogue's).
    if (o.stars > 0) {
      std::vector<double> x, y, radius, flux;
      for (const CellStar& s : cell.stars) x.push_back(s.x + 1), y.push_back(s.y + 1), radius.push_back(s.radius),
                                            flux.push_back(s.flux * b.flux_scale);
      f.write_table("STARS", {{"x", false, x}, {"y", false, y}, {"radius", false, radius}, {"flux", false, flux}});
    }
  });
}

void write_cell_truth(const std::string& path, const CellSimulator& simulator, double g1, double g2,
                      std::span<const CellTruthRow> rows, const std::vector<std::string>& band_names, bool overwrite) {
  using Get = double (*)(const CellTruthRow&);
  struct Spec {
    const char* name;
    bool integer;
    Get get;
  };
  static const Spec specs[] = {
      {"cell", true, [](const CellTruthRow& r) { return static_cast<double>(r.cell); }},
      {"id", true, [](const CellTruthRow& r) { return static_cast<double>(r.object.id); }},
      {"x", false, [](const CellTruthRow& r) { return r.object.x; }},
      {"y", false, [](const CellTruthRow& r) { return r.object.y; }},
      {"flux", false, [](const CellTruthRow& r) { return r.object.flux; }},
      {"hlr", false, [](const CellTruthRow& r) { return r.object.hlr; }},
      {"bulge_frac", false, [](const CellTruthRow& r) { return r.object.bulge_frac; }},
      {"e1_int", false, [](const CellTruthRow& r) { return r.object.e1_int; }},
      {"e2_int", false, [](const CellTruthRow& r) { return r.object.e2_int; }},
      {"e1_obs", false, [](const CellTruthRow& r) { return r.object.e1_obs; }},
      {"e2_obs", false, [](const CellTruthRow& r) { return r.object.e2_obs; }},
      {"snr", false, [](const CellTruthRow& r) { return r.object.snr; }},
  };
  std::vector<FitsFile::OutputColumn> columns;
  for (const Spec& s : specs) {
    FitsFile::OutputColumn c{s.name, s.integer, {}};
    c.values.reserve(rows.size());
    for (const CellTruthRow& r : rows) c.values.push_back(s.get(r));
    columns.push_back(std::move(c));
  }
  columns.push_back({"g1", false, std::vector<double>(rows.size(), g1)});
  columns.push_back({"g2", false, std::vector<double>(rows.size(), g2)});
  for (std::size_t b = 0; b < band_names.size(); ++b) {
    FitsFile::OutputColumn c{"flux_" + band_names[b], false, {}};
    for (const CellTruthRow& r : rows) c.values.push_back(r.object.flux * simulator.bands().at(b).flux_scale);
    columns.push_back(std::move(c));
  }
  write_partial_then_rename(path, overwrite, [&](FitsFile& f) {
    f.write_empty_image();
    write_settings(f, simulator);
    f.write_key("SHEAR1", g1, "the shear g1 (reduced) of every galaxy");
    f.write_key("SHEAR2", g2, "the shear g2 (reduced)");
    f.write_key("NOISESIG", simulator.bands().front().noise_sigma, "white noise sigma per pixel, every band");
    f.write_table("TRUTH", columns);
  });
}

}  // namespace stampede::io
