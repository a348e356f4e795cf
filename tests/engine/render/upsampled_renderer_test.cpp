// Tests of the paper-faithful renderer against analytic results, finite differences and the
// independent GalSim reference stamps.
#include "engine/render/upsampled_renderer.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <random>

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
  PsfOptions psf;
  psf.moffat = {beta, fwhm, e1, e2, 0.0};
  std::string err;
  auto k = PsfKernel::build(psf, GridGeometry(ro), plans, &err);
  EXPECT_TRUE(k) << err;
  return k;
}

// Must-show 1: the analytic Jacobian equals central finite differences of the rendered model, for
// every free parameter, at random parameter sets that include |e| near the mirror, radii inside
// the softening region and centres off the stamp centre.
TEST(UpsampledRenderer, JacobianMatchesFiniteDifferences) {
  RenderOptions ro;
  ro.stamp_size = 25;
  FftPlanCache plans(FftPlanning::kEstimate);
  auto kernel = moffat_kernel(ro, plans);
  UpsampledRenderer renderer(ro, ModelOptions{}, kernel, plans);
  const int npix = ro.stamp_size * ro.stamp_size;
  const std::array<Param, 7> free = {Param::kX0, Param::kY0, Param::kE1, Param::kE2, Param::kRadius, Param::kBulgeA, Param::kDiscA};
  std::vector<double> model(npix), plus(npix), minus(npix);
  std::vector<std::vector<double>> jac(7, std::vector<double>(npix));
  std::array<double*, 7> cols;
  for (int k = 0; k < 7; ++k) cols[k] = jac[k].data();

  std::mt19937 rng(12345);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  const double transition = 0.4 / ro.upsampling;  // softening radius in pixels
  int tested = 0;
  double worst_relative = 0;
  for (int set = 0; set < 24; ++set) {
    ParamVector p = default_params();
    // Centre away from the stamp centre; keep clear of sub-pixel boundaries by more than the FD
    // step, where the central U2 block jumps (the model is only piecewise smooth in x0, y0).
    const double step = 1.0 / ro.upsampling;
    auto centre = [&](double c) {
      double x = c + (u(rng) - 0.5) * 6.0;
      const double frac = (x + 0.5) / step - std::floor((x + 0.5) / step);
      if (frac < 0.05 || frac > 0.95) x += 0.2 * step;
      return x;
    };
    p[index(Param::kX0)] = centre(12.0);
    p[index(Param::kY0)] = centre(12.0);
    double emag = 0.9 * u(rng);
    if (set % 4 == 1) emag = 0.93 + 0.04 * u(rng);  // either side of the mirror at 0.95
    const double theta = M_PI * u(rng);
    p[index(Param::kE1)] = emag * std::cos(2 * theta);
    p[index(Param::kE2)] = emag * std::sin(2 * theta);
    double r = 0.5 + 2.5 * u(rng);
    if (set % 4 == 2) r = transition * (0.2 + 0.7 * u(rng));  // inside the softening region
    p[index(Param::kRadius)] = r;
    p[index(Param::kBulgeA)] = 500.0 * u(rng);
    p[index(Param::kDiscA)] = 50.0 * u(rng);
    ASSERT_EQ(renderer.render_with_jacobian(p, free, model, cols), RenderStatus::kOk);
    double peak = 0;
    for (double v : model) peak = std::max(peak, std::abs(v));
    for (int k = 0; k < 7; ++k) {
      const int i = index(free[k]);
      // Steps small against each parameter's scale; central differences are O(h^2).
      const double h = (i <= 1) ? 1e-5 : (i <= 3) ? 1e-6 : (i == 4) ? 1e-6 * std::max(r, transition) : 1e-4 * std::max(1.0, p[i]);
      ParamVector pp = p, pm = p;
      pp[i] += h;
      pm[i] -= h;
      ASSERT_EQ(renderer.render(pp, plus), RenderStatus::kOk);
      ASSERT_EQ(renderer.render(pm, minus), RenderStatus::kOk);
      double max_fd = 0, max_diff = 0;
      for (int q = 0; q < npix; ++q) {
        const double fd = (plus[q] - minus[q]) / (2 * h);
        max_fd = std::max(max_fd, std::abs(fd));
        max_diff = std::max(max_diff, std::abs(fd - jac[k][q]));
      }
      // Relative 1e-5 of the column's largest entry; the floor 1e-9 * peak / h covers the rounding
      // error of a central difference of images whose values are ~peak (eps 1e-16 * ~1e3 terms).
      const double tol = 1e-5 * max_fd + 1e-10 * peak / h;
      EXPECT_LE(max_diff, tol) << "set " << set << " parameter " << param_name(free[k]) << " |e|=" << emag
                               << " r=" << r << " max|fd|=" << max_fd;
      worst_relative = std::max(worst_relative, max_diff / max_fd);
      ++tested;
    }
  }
  EXPECT_EQ(tested, 24 * 7);
  std::printf("Jacobian: worst max|J - FD| / max|FD| over %d columns = %.2e\n", tested, worst_relative);
}

// Must-show 2: rendered flux equals the analytic Sérsic flux in a large stamp. The disc holds
// at the defaults; the de Vaucouleurs cusp needs the central region resolved (at defaults the
// 7x7 midpoint rule of the central sub-pixels leaves the bulge ~0.2-0.5% short: printed).
TEST(UpsampledRenderer, RenderedFluxEqualsAnalyticSersicFlux) {
  FftPlanCache plans(FftPlanning::kEstimate);
  struct Case {
    double bulge_a, disc_a, r, e1;
    int nu, u2;
    bool asserted;
  };
  // Round bulges with r_e = 1.5 px: beyond the 80 px inscribed circle (53 r_e) lies 3e-4 of the
  // flux (de Vaucouleurs wings are heavy: 1.5% lies beyond 16 r_e).
  for (const Case& c : {Case{0, 10, 3.0, 0.2, 3, 7, true}, Case{2000, 0, 1.5, 0.0, 3, 7, false},
                        Case{2000, 0, 1.5, 0.0, 25, 25, true}, Case{4000, 10, 1.5, 0.0, 25, 25, true}}) {
    RenderOptions ro;
    ro.stamp_size = 160;
    ro.n_central_pixels_to_upsample = c.nu;
    ro.n_central_pixel_upsampling = c.u2;
    auto kernel = moffat_kernel(ro, plans);
    UpsampledRenderer renderer(ro, ModelOptions{}, kernel, plans);
    std::vector<double> model(ro.stamp_size * ro.stamp_size);
    ParamVector p = default_params();
    p[index(Param::kX0)] = 79.3;
    p[index(Param::kY0)] = 79.6;
    p[index(Param::kE1)] = c.e1;
    p[index(Param::kE2)] = 0.0;
    p[index(Param::kRadius)] = c.r;
    p[index(Param::kBulgeA)] = c.bulge_a;
    p[index(Param::kDiscA)] = c.disc_a;
    ASSERT_EQ(renderer.render(p, model), RenderStatus::kOk);
    double sum = 0;
    for (double v : model) sum += v;
    double fb, fd;
    renderer.galaxy_model().fluxes(p, &fb, &fd);
    std::printf("bulge A %g disc A %g r %g N_u %d U2 %d: rendered / analytic flux = %.6f\n", c.bulge_a, c.disc_a, c.r,
                c.nu, c.u2, sum / (fb + fd));
    if (c.asserted) {
      EXPECT_NEAR(sum / (fb + fd), 1.0, 1e-3) << "bulge A " << c.bulge_a << " disc A " << c.disc_a;
    }
  }
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
  PsfOptions airy;
  airy.type = PsfType::kAiry;
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

struct CaseError {
  double worst_over_peak = 0;
};

CaseError compare_case(const testing::RenderCase& c, int u1, int nu, int u2, int padding, FftPlanCache& plans) {
  RenderOptions ro;
  ro.stamp_size = c.stamp;
  ro.upsampling = u1;
  ro.n_central_pixels_to_upsample = nu;
  ro.n_central_pixel_upsampling = u2;
  ro.padding = padding;
  std::string err;
  auto psf = PsfKernel::build(testing::case_psf(c), GridGeometry(ro), plans, &err);
  UpsampledRenderer renderer(ro, ModelOptions{}, psf, plans);
  std::vector<double> model(c.stamp * c.stamp);
  EXPECT_EQ(renderer.render(testing::case_truth(c), model), RenderStatus::kOk);
  double peak = 0, worst = 0;
  for (std::size_t i = 0; i < model.size(); ++i) {
    peak = std::max(peak, c.image[i]);
    worst = std::max(worst, std::abs(model[i] - c.image[i]));
  }
  return {worst / peak};
}

// Must-show 3: every GalSim reference case, rendered from its parameters. At the paper's defaults
// the error is the scheme's own discretisation (sub-pixel midpoint sampling, O(h^2)); it shrinks
// with resolution, and at high resolution with padding the renderer agrees with GalSim to 1e-3 of
// the peak, which no convention error (centre, ellipticity, radius, PSF) could survive.
TEST(UpsampledRenderer, MatchesGalSimReferenceCases) {
  const auto cases = testing::load_render_cases();
  ASSERT_EQ(cases.size(), 22u);
  FftPlanCache plans(FftPlanning::kEstimate);
  double sum_defaults = 0, sum_finer = 0;
  std::printf("%4s %5s %6s %7s | %10s %10s %10s\n", "case", "hlr", "B/T", "|e|", "U1=5,Nu=3", "U1=7,Nu=5", "converged");
  for (const auto& c : cases) {
    const double defaults = compare_case(c, 5, 3, 7, 4, plans).worst_over_peak;
    const double finer = compare_case(c, 7, 5, 7, 4, plans).worst_over_peak;
    const double converged = compare_case(c, 15, 15, 15, 6, plans).worst_over_peak;
    std::printf("%4d %5.2f %6.2f %7.3f | %10.2e %10.2e %10.2e\n", c.id, c.hlr, c.bulge_flux / (c.bulge_flux + c.disc_flux),
                std::hypot(c.e1, c.e2), defaults, finer, converged);
    EXPECT_LT(converged, 1e-3) << "case " << c.id;
    sum_defaults += defaults;
    sum_finer += finer;
    // At defaults the midpoint rule leaves up to 1.3e-2 of the peak for small bulges (r_e <= 1.5 px)
    // and 1.6e-2 for the tiny disc (r_e = 0.3 px = 1.5 sub-pixels); README "Accuracy".
    EXPECT_LT(defaults, 2e-2) << "case " << c.id;
  }
  // Shrinking with upsampling: on average over the cases (one case, 12, is flat within 6%).
  EXPECT_LT(sum_finer, 0.6 * sum_defaults);
}

}  // namespace
}  // namespace stampede
