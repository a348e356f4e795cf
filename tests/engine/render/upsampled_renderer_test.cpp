// Tests of the paper-faithful renderer's own properties (its PSF kernels, a point source against
// GalSim's PSF); what every renderer must pass is in renderer_contract_test.cpp.
#include "engine/render/upsampled_renderer.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>

#include "kernels/sersic.hpp"
#include "support/reference_data.hpp"

namespace stampede {
namespace {

ParamVector default_params() {
  ParamVector p = ParameterSet::default_values();
  return p;
}

std::shared_ptr<const PsfKernel> moffat_kernel(const RenderOptions& ro, FftPlanCache& plans, double beta = 3.0,
                                               double fwhm = 2.85, double e1 = 0.0, double e2 = 0.05) {
  std::string err;
  auto k = PsfKernel::build(PsfModel::Moffat({beta, fwhm, e1, e2, 0.0}), GridGeometry(ro), plans, &err);
  EXPECT_TRUE(k) << err;
  return k;
}

// Must-show 2: PSF kernels integrate to 1 on a grid that holds the PSF.
TEST(UpsampledRenderer, PsfKernelsIntegrateToOne) {
  RenderOptions ro;
  ro.stamp_size = 64;
  FftPlanCache plans(FftPlanning::kEstimate);
  auto moffat = moffat_kernel(ro, plans, 3.5, 2.85, 0.1, -0.05);
  // An untruncated beta = 3.5 Moffat leaves (1 + (32/alpha)^2)^(1-beta) ~ 1e-6 outside 32 px.
  EXPECT_NEAR(moffat->grid_flux(), 1.0, 1e-5);
  EXPECT_NEAR(moffat->spectrum()[0].real() * std::pow(GridGeometry(ro).grid_size(), 2), moffat->grid_flux(), 1e-12);
  PsfModel airy;
  airy.kind = PsfKind::kAiry;
  airy.airy = {2.0, 0.0};
  std::string err;
  auto a = PsfKernel::build(airy, GridGeometry(ro), plans, &err);
  ASSERT_TRUE(a) << err;
  // Encircled energy of an Airy disc within R ~ 32 px (a square of side 64 holds slightly more):
  // 1 - J0(x)^2 - J1(x)^2 at x = pi R / L; the wings beyond hold ~ 2L/(pi^2 R) ~ 1.3%.
  const double x = M_PI * 32.0 / 2.0;
  const double inside_circle = 1 - std::pow(std::cyl_bessel_j(0.0, x), 2) - std::pow(std::cyl_bessel_j(1.0, x), 2);
  EXPECT_GT(a->grid_flux(), inside_circle);
  EXPECT_LT(a->grid_flux(), 1.0);
}

// Must-show 2: a point-like galaxy reproduces the PSF. The reference is GalSim's own
// pixel-integrated PSF image of the GREAT08-mini sets, centred at (19, 19).
TEST(UpsampledRenderer, PointLikeGalaxyReproducesGalSimPsf) {
  io::FitsFile f = io::FitsFile::open_read(testing::data_path("galsim-great08-mini/nf/psf_0.fits"));
  const std::vector<double> psf_image = f.read_image();
  RenderOptions ro;
  ro.stamp_size = 39;
  FftPlanCache plans(FftPlanning::kEstimate);
  auto kernel = moffat_kernel(ro, plans, f.key_double("PSFBETA"), f.key_double("PSFFWHM"), f.key_double("PSFE1"),
                              f.key_double("PSFE2"));
  UpsampledRenderer renderer(ro, ModelOptions{}, kernel, plans);
  ParamVector p = default_params();
  p[index(Param::kX0)] = 19.0;
  p[index(Param::kY0)] = 19.0;
  p[index(Param::kE1)] = 0.0;
  p[index(Param::kE2)] = 0.0;
  p[index(Param::kRadius)] = 0.0;  // softened to R/2 = 0.04 px: a point at this resolution
  p[index(Param::kBulgeA)] = 0.0;
  p[index(Param::kDiscA)] = 1.0 / kernels::sersic_flux_per_amplitude(0.2 / ro.upsampling, 1.0);
  std::vector<double> model(39 * 39);
  ASSERT_EQ(renderer.render(p, model), RenderStatus::kOk);
  double sum = 0, peak = 0, worst = 0;
  for (std::size_t i = 0; i < model.size(); ++i) sum += model[i];
  for (std::size_t i = 0; i < model.size(); ++i) {
    peak = std::max(peak, psf_image[i]);
    worst = std::max(worst, std::abs(model[i] / sum - psf_image[i] / f.key_double("PSFSUM")));
  }
  // GalSim's image is accurate to ~5e-5 of the peak (its README); ours to the PSF sampling at U1=5.
  EXPECT_LT(worst / peak, 1e-3);
  std::printf("point source vs GalSim PSF: worst |diff| / peak = %.2e\n", worst / peak);
}

}  // namespace
}  // namespace stampede
