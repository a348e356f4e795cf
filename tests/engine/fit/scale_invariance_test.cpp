// Must-show 2 of issue 17: a fit is invariant to a common scale of the data (and of the noise):
// GalSim GREAT08-mini stamps multiplied by 1e-8 ... 1e8 give the same e to 1e-6, unweighted and
// weighted with noise_sigma scaled alike (and chi2, fluxes, errors and S/N follow in their units).
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>

#include "engine/fit/fitter.hpp"
#include "engine/render/psf_kernel.hpp"
#include "io/stamp_grid.hpp"
#include "support/reference_data.hpp"

namespace stampede {
namespace {

constexpr int kObjects = 16;  // the first 16 stamps of set 0

struct Stamps {
  FitterOptions options;
  PsfModel psf;
  std::vector<double> pixels;  // kObjects stamps, each stamp_size^2
};

Stamps load(const std::string& kind) {
  io::StampGridReader grid(testing::data_path("galsim-great08-mini/" + kind + "/set_0.fits"));
  io::FitsFile& h = grid.file();
  Stamps s;
  s.options.renderer = RendererKind::kUpsampled;  // the PsfKernel below is the upsampled renderer's
  s.options.render.stamp_size = grid.stamp_size();
  s.options.noise_sigma = h.key_double("NOISESIG");
  s.psf.moffat = {h.key_double("PSFBETA"), h.key_double("PSFFWHM"), h.key_double("PSFE1"), h.key_double("PSFE2"), 0.0};
  const std::size_t npix = static_cast<std::size_t>(grid.stamp_size()) * grid.stamp_size();
  std::vector<double> row(grid.grid_nx() * npix);
  grid.read_stamp_row(0, row);
  s.pixels.assign(row.begin(), row.begin() + kObjects * npix);
  return s;
}

double relative_change(double scaled, double base) { return std::abs(scaled - base) / std::abs(base); }

// Fits every stamp at each scale (noise_sigma scaled with the data) and returns the largest
// |e - e(scale 1)| over objects and scales. At every scale each fit has the same status and flags,
// e to 1e-6, and chi2, flux, errors and snr in their units to 1e-6 relative; at a power of two the
// change of units is exact, so e is identical.
double worst_e_change(const Stamps& s) {
  FftPlanCache plans(FftPlanning::kEstimate);
  std::string err;
  auto kernel = PsfKernel::build(s.psf, GridGeometry(s.options.render), plans, &err);
  EXPECT_TRUE(kernel) << err;
  const std::size_t npix = s.pixels.size() / kObjects;
  const bool weighted = s.options.noise_sigma > 0;
  auto fit_all = [&](double scale) {
    FitterOptions fo = s.options;
    fo.noise_sigma *= scale;
    Fitter fitter(fo, kernel, plans);
    std::vector<double> stamp(npix);
    std::vector<FitResult> out;
    for (int i = 0; i < kObjects; ++i) {
      for (std::size_t k = 0; k < npix; ++k) stamp[k] = s.pixels[i * npix + k] * scale;
      out.push_back(fitter.fit(stamp));
      EXPECT_EQ(out.back().status, FitStatus::kOk) << "object " << i << " at scale " << scale;
    }
    return out;
  };
  const std::vector<FitResult> base = fit_all(1.0);
  std::vector<double> scales = {std::ldexp(1.0, -30), std::ldexp(1.0, 30)};
  for (int decade = -8; decade <= 8; ++decade) scales.push_back(std::pow(10.0, decade));
  double worst = 0;
  for (double scale : scales) {
    const std::vector<FitResult> r = fit_all(scale);
    const bool exact = std::ilogb(scale) == std::log2(scale);
    const double chi2_unit = weighted ? 1.0 : scale * scale;  // chi2 is in data units when unweighted
    const double err_unit = weighted ? 1.0 : 1.0 / scale;     // and the errors per unit data
    double here = 0;
    for (int i = 0; i < kObjects; ++i) {
      const FitResult& a = base[i];
      const FitResult& b = r[i];
      const std::string at = "object " + std::to_string(i) + " at scale " + std::to_string(scale);
      EXPECT_EQ(b.flags, a.flags) << at;
      for (Param p : {Param::kE1, Param::kE2}) {
        const double d = std::abs(b.params[index(p)] - a.params[index(p)]);
        here = std::max(here, std::isnan(d) ? INFINITY : d);
        EXPECT_LE(d, exact ? 0.0 : 1e-6) << at << " " << param_name(p);
      }
      EXPECT_LE(relative_change(b.chi2 / chi2_unit, a.chi2), 1e-6) << at;
      EXPECT_LE(relative_change(b.flux / scale, a.flux), 1e-6) << at;
      EXPECT_LE(relative_change(b.params[index(Param::kDiscA)] / scale, a.params[index(Param::kDiscA)]), 1e-6) << at;
      EXPECT_LE(relative_change(b.e1_err / err_unit, a.e1_err), 1e-6) << at;
      if (weighted) {
        EXPECT_LE(relative_change(b.snr, a.snr), 1e-6) << at;
      }
    }
    std::printf("scale %.3g: max |delta e| = %.2e\n", scale, here);
    worst = std::max(worst, here);
  }
  return worst;
}

TEST(ScaleInvariance, UnweightedNoiseFreeStamps) {
  const Stamps s = load("nf");
  ASSERT_EQ(s.options.noise_sigma, 0.0);
  EXPECT_LE(worst_e_change(s), 1e-6);
}

TEST(ScaleInvariance, WeightedStampsWithTheNoiseScaledAlike) {
  const Stamps s = load("snr40");
  ASSERT_GT(s.options.noise_sigma, 0.0);
  EXPECT_LE(worst_e_change(s), 1e-6);
}

}  // namespace
}  // namespace stampede
