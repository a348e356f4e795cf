// Access to the independent GalSim reference data in ../shared/data (see its README.md), and the
// fitter options that describe one reference case.
#pragma once

#include <string>
#include <vector>

#include "engine/fit/fitter.hpp"
#include "engine/model/psf_model.hpp"
#include "io/fits_file.hpp"
#include "kernels/sersic.hpp"
#include <cstdio>

namespace stampede::testing {

inline std::string data_path(const std::string& rel) { return std::string(STAMPEDE_DATA_DIR) + "/" + rel; }

struct RenderCase {
  int id = 0;
  int stamp = 0;
  double x0 = 0, y0 = 0, e1 = 0, e2 = 0, hlr = 0, bulge_flux = 0, disc_flux = 0;
  double psf_fwhm = 0, psf_beta = 0, psf_e1 = 0, psf_e2 = 0, stamp_sum = 0;
  std::vector<double> image;  // stamp x stamp, GalSim pixel integrals
};

inline std::vector<RenderCase> load_render_cases() {
  io::FitsFile f = io::FitsFile::open_read(data_path("galsim-reference/render_cases.fits"));
  f.move_to("CASES");
  const long long n = f.table_rows();
  auto col = [&](const char* name) { return f.read_column(name); };
  const auto id = col("case"), stamp = col("stamp"), x0 = col("x0"), y0 = col("y0"), e1 = col("e1"), e2 = col("e2"),
             hlr = col("hlr"), bf = col("bulge_flux"), df = col("disc_flux"), fwhm = col("psf_fwhm"),
             beta = col("psf_beta"), pe1 = col("psf_e1"), pe2 = col("psf_e2"), sum = col("stamp_sum");
  std::vector<RenderCase> cases(n);
  for (long long i = 0; i < n; ++i) {
    RenderCase& c = cases[i];
    c.id = static_cast<int>(id[i]);
    c.stamp = static_cast<int>(stamp[i]);
    c.x0 = x0[i], c.y0 = y0[i], c.e1 = e1[i], c.e2 = e2[i], c.hlr = hlr[i];
    c.bulge_flux = bf[i], c.disc_flux = df[i], c.psf_fwhm = fwhm[i], c.psf_beta = beta[i];
    c.psf_e1 = pe1[i], c.psf_e2 = pe2[i], c.stamp_sum = sum[i];
    char name[16];
    std::snprintf(name, sizeof name, "CASE%02d", c.id);
    f.move_to(std::string(name));
    c.image = f.read_image();
  }
  return cases;
}

inline PsfModel case_psf(const RenderCase& c) {
  PsfModel psf;
  psf.kind = PsfKind::kMoffat;
  psf.moffat = {c.psf_beta, c.psf_fwhm, c.psf_e1, c.psf_e2, 0.0};
  return psf;
}

// The true parameter vector of a case (amplitudes from fluxes; equal bulge and disc radii).
inline ParamVector case_truth(const RenderCase& c) {
  ParamVector p;
  for (int k = 0; k < kNumParams; ++k) p[k] = ParameterSet::defaults()[k].start;
  p[index(Param::kX0)] = c.x0;
  p[index(Param::kY0)] = c.y0;
  p[index(Param::kE1)] = c.e1;
  p[index(Param::kE2)] = c.e2;
  p[index(Param::kRadius)] = c.hlr;
  p[index(Param::kBulgeA)] = c.bulge_flux / kernels::sersic_flux_per_amplitude(c.hlr, 4.0);
  p[index(Param::kDiscA)] = c.disc_flux / kernels::sersic_flux_per_amplitude(c.hlr, 1.0);
  return p;
}

}  // namespace stampede::testing
