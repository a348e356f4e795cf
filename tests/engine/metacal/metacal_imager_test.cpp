// Tests for metacalibration's image operations (engine/metacal/metacal_imager, metacal_filters):
// against the analytic truth (the simulator's exact drawing of the sheared galaxy convolved with
// the reconvolution PSF) and against GalSim's reference images.
#include "engine/metacal/metacal_imager.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <memory>
#include <vector>

#include "engine/metacal/reconvolution_psf.hpp"
#include "engine/sim/sim_renderer.hpp"
#include "support/reference_data.hpp"
#include "support/sky_to_pixel.hpp"

namespace stampede {
namespace {

PsfModel moffat(double beta, double fwhm, double e1, double e2) {
  PsfModel p;
  p.kind = PsfKind::kMoffat;
  p.moffat = {beta, fwhm, e1, e2, 0.0};
  return p;
}

// max |a - b| over the stamp, and over pixels within `radius` of (cx, cy) when radius > 0.
double max_difference(const std::vector<double>& a, std::span<const double> b, int size, double cx = 0, double cy = 0,
                      double radius = 0) {
  double worst = 0;
  for (int y = 0; y < size; ++y)
    for (int x = 0; x < size; ++x) {
      if (radius > 0 && std::hypot(x - cx, y - cy) > radius) continue;
      worst = std::max(worst, std::abs(a[y * size + x] - b[y * size + x]));
    }
  return worst;
}

struct Drawn {
  std::vector<double> observed;
  std::array<std::vector<double>, kNumMetacalTypes> expected;  // sheared galaxy (x) Gamma (x) pixel
};

// The galaxy drawn through `psf`, and each metacal type's truth drawn through `gamma`: a round
// profile sheared by g is the same profile with e = g (reduced shear), about its own centre.
Drawn draw_round(const SimComponent& galaxy, const PsfModel& psf, const PsfModel& gamma, double step, int size) {
  SimRenderer::Options opt;
  opt.sersic_indices = {0.5, 1.0};
  SimWorkspace ws;
  Drawn d;
  d.observed.resize(size * size);
  SimRenderer(psf, opt).render({&galaxy, 1}, size, d.observed, ws);
  const SimRenderer reconvolved(gamma, opt);
  for (MetacalType t : kMetacalTypes) {
    SimComponent g = galaxy;
    const auto shear = metacal_shear(t, step);
    g.e1 = shear[0];
    g.e2 = shear[1];
    auto& e = d.expected[static_cast<int>(t)];
    e.resize(size * size);
    reconvolved.render({&g, 1}, size, e, ws);
  }
  return d;
}

// Must-show 1: a round analytic profile through deconvolve-shear-reconvolve matches the
// analytically sheared profile convolved with the new PSF to <= 1e-5 of the peak, every type. A
// Gaussian, whose transform has vanished by the Nyquist frequency, isolates the operations; a
// cuspy exponential's observed stamp is aliased (its transform falls only as k^-3), which no
// operation on the samples can undo: there the sheared types must add <= 1e-5 of the peak to the
// noshear image's alias floor.
TEST(MetacalImager, ARoundProfileShearedThroughThePathMatchesTheAnalyticShear) {
  const int size = 48;
  const PsfModel psf = moffat(3.0, 2.85, 0.0, 0.05), gamma = moffat(3.0, 3.135, 0.0, 0.0);
  for (const SimComponent galaxy : {SimComponent{0.5, 1000.0, 2.0, 0.0, 0.0, 23.3, 23.6},
                                    SimComponent{0.5, 1000.0, 1.2, 0.0, 0.0, 22.5, 24.0},
                                    SimComponent{1.0, 1000.0, 2.0, 0.0, 0.0, 23.3, 23.6},
                                    SimComponent{1.0, 1000.0, 1.2, 0.0, 0.0, 22.5, 24.0}}) {
    const double step = 0.01;
    const Drawn d = draw_round(galaxy, psf, gamma, step, size);
    std::string error;
    const auto filters = MetacalFilters::build(psf, gamma, step, MetacalImager::padded_size(size), &error);
    ASSERT_TRUE(filters) << error;
    MetacalImager imager(size, filters->period(), FftPlanning::kEstimate);
    std::vector<double> out(kNumMetacalTypes * size * size);
    imager.make_images(d.observed, *filters, galaxy.x, galaxy.y, out);
    double noshear = 0;
    for (MetacalType t : kMetacalTypes) {
      const auto& e = d.expected[static_cast<int>(t)];
      const double peak = *std::max_element(e.begin(), e.end());
      const double diff =
          max_difference(e, std::span<const double>(out).subspan(static_cast<int>(t) * size * size, size * size), size) / peak;
      std::printf("n %.1f hlr %.1f %-7s max |diff| / peak = %.2e\n", galaxy.sersic_n, galaxy.half_light_radius,
                  metacal_type_name(t), diff);
      if (t == MetacalType::kNoshear) noshear = diff;
      if (galaxy.sersic_n == 0.5) {
        EXPECT_LE(diff, 1e-5) << metacal_type_name(t);
      } else {
        EXPECT_LE(diff, noshear + 1e-5) << metacal_type_name(t);
        EXPECT_LE(noshear, 3e-5);  // the alias floor measured: 1.3e-5 (hlr 2), 2.4e-5 (hlr 1.2)
      }
    }
  }
}

// A metadetection cell's path (stamps of 128 px or more: the stretches by Bluestein's transform
// straight from the filtered spectrum, the shears' last pass on the stamp's rows alone), in double
// and in single precision: the same analytic truth to <= 1e-7 of the peak in double (a Gaussian, no
// alias floor; measured 2e-8) and <= 1e-6 in single (measured 2e-7), every type.
TEST(MetacalImager, ACellsPathInEitherPrecisionMatchesTheAnalyticShear) {
  const int size = 130;
  const PsfModel psf = moffat(3.0, 2.85, 0.0, 0.05), gamma = moffat(3.0, 3.135, 0.0, 0.0);
  const SimComponent galaxy{0.5, 1000.0, 2.5, 0.0, 0.0, 61.3, 66.8};
  const double step = 0.01;
  const Drawn d = draw_round(galaxy, psf, gamma, step, size);
  std::string error;
  const int period = MetacalImager::padded_size(size, 16);
  const auto filters = MetacalFilters::build(psf, gamma, step, period, &error);
  ASSERT_TRUE(filters) << error;
  const std::size_t npix = static_cast<std::size_t>(size) * size;
  std::vector<double> in_double(kNumMetacalTypes * npix), in_single(kNumMetacalTypes * npix);
  MetacalImager(size, period, FftPlanning::kEstimate).make_images(d.observed, *filters, galaxy.x, galaxy.y, in_double);
  BasicMetacalImager<float>(size, period, FftPlanning::kEstimate)
      .make_images(d.observed, *filters, galaxy.x, galaxy.y, in_single);
  for (MetacalType t : kMetacalTypes) {
    const auto& e = d.expected[static_cast<int>(t)];
    const double peak = *std::max_element(e.begin(), e.end());
    const std::size_t at = static_cast<int>(t) * npix;
    const std::vector<double> ours_double(in_double.begin() + at, in_double.begin() + at + npix);
    const double diff_double = max_difference(e, std::span<const double>(in_double).subspan(at, npix), size) / peak;
    const double diff_single = max_difference(e, std::span<const double>(in_single).subspan(at, npix), size) / peak;
    const double between = max_difference(ours_double, std::span<const double>(in_single).subspan(at, npix), size) / peak;
    std::printf("cell %-7s max |diff| / peak: double %.2e, single %.2e, between %.2e\n", metacal_type_name(t),
                diff_double, diff_single, between);
    EXPECT_LE(diff_double, 1e-7) << metacal_type_name(t);
    EXPECT_LE(diff_single, 1e-6) << metacal_type_name(t);
    EXPECT_LE(between, 1e-6) << metacal_type_name(t);
  }
}

// delta -> 0: every sheared image is the noshear one, which is the input reconvolved with Gamma.
TEST(MetacalImager, AVanishingStepGivesTheInputReconvolved) {
  const int size = 40;
  const PsfModel psf = moffat(3.0, 2.85, 0.03, -0.04), gamma = moffat(3.0, 3.3, 0.0, 0.0);
  const SimComponent galaxy{1.0, 500.0, 1.8, 0.0, 0.0, 19.7, 19.2};
  const Drawn d = draw_round(galaxy, psf, gamma, 1e-9, size);
  std::string error;
  const auto filters = MetacalFilters::build(psf, gamma, 1e-9, MetacalImager::padded_size(size), &error);
  ASSERT_TRUE(filters) << error;
  MetacalImager imager(size, filters->period(), FftPlanning::kEstimate);
  std::vector<double> out(kNumMetacalTypes * size * size);
  imager.make_images(d.observed, *filters, 19.5, 19.5, out);
  const auto& noshear = d.expected[0];
  const double peak = *std::max_element(noshear.begin(), noshear.end());
  const std::span<const double> all(out);
  EXPECT_LE(max_difference(noshear, all.subspan(0, size * size), size), 1e-5 * peak);
  const std::vector<double> ours(all.begin(), all.begin() + size * size);
  for (int t = 1; t < kNumMetacalTypes; ++t)
    EXPECT_LE(max_difference(ours, all.subspan(t * size * size, size * size), size), 1e-7 * peak)
        << metacal_type_name(static_cast<MetacalType>(t));
}

// The PSF given as its pixel-integrated image (as PSFEx or a Python user gives it) instead of its
// analytic form, with the same Gamma: the same images to the image's own aliasing. And the Gamma
// chosen for an image PSF is wide enough for every filter.
TEST(MetacalImager, AnImagePsfGivesTheAnalyticPsfsImages) {
  const int size = 48;
  const PsfModel psf = moffat(3.0, 2.85, 0.0, 0.05), gamma = moffat(3.0, 3.135, 0.0, 0.0);
  const SimComponent galaxy{1.0, 1000.0, 2.0, 0.0, 0.0, 23.3, 23.6};
  const Drawn d = draw_round(galaxy, psf, gamma, 0.01, size);
  auto image = std::make_shared<PsfImage>();
  image->nx = image->ny = 41;
  image->pixels.resize(41 * 41);
  SimWorkspace ws;
  SimRenderer(psf, {}).render_psf(41, 1.0, 20.0, 20.0, true, image->pixels, ws);
  const int period = MetacalImager::padded_size(size);
  std::string error;
  const auto analytic = MetacalFilters::build(psf, gamma, 0.01, period, &error);
  const auto sampled = MetacalFilters::build(PsfModel::Image(image), gamma, 0.01, period, &error);
  ASSERT_TRUE(analytic && sampled) << error;
  MetacalImager imager(size, period, FftPlanning::kEstimate);
  std::vector<double> a(kNumMetacalTypes * size * size), b(a.size());
  imager.make_images(d.observed, *analytic, galaxy.x, galaxy.y, a);
  imager.make_images(d.observed, *sampled, galaxy.x, galaxy.y, b);
  const double peak = *std::max_element(d.expected[0].begin(), d.expected[0].end());
  double worst = 0;
  for (std::size_t i = 0; i < a.size(); ++i) worst = std::max(worst, std::abs(a[i] - b[i]));
  std::printf("image PSF against analytic PSF, same Gamma: max |diff| / peak = %.2e\n", worst / peak);
  // Measured 2.9e-4: the image's transform sums the aliases of PSF x pixel beyond the Nyquist
  // frequency (the analytic form has none), which matters where both are ~1e-2 of the centre.
  EXPECT_LE(worst, 4e-4 * peak);
  MetacalOptions mo;
  mo.reconvolution = ReconvolutionRule::kMoffat;  // the Moffat rule's search on an image PSF
  const auto chosen = reconvolution_filters(PsfModel::Image(image), mo, period, &error);
  ASSERT_TRUE(chosen) << error;
  std::printf("Gamma chosen for the image PSF: FWHM %.3f px (the analytic rule's: %.3f)\n",
              chosen->reconvolution().moffat.fwhm, 2.85 * 1.02 * std::sqrt(1.05 / 0.95));
  EXPECT_GT(chosen->reconvolution().moffat.fwhm, 2.85);
  EXPECT_LT(chosen->reconvolution().moffat.fwhm, 2.85 * 1.15);
}

// A cutout seen through a WCS Jacobian (rotated, scaled, sheared): the shear applied on the sky
// (A^-1 = J^-1 A_sky^-1 J in the pixels, not symmetric) and Gamma round on the sky. A round
// Gaussian galaxy on the sky, drawn in the cutout's pixels through its PSF, must give, per type,
// the galaxy sheared on the sky drawn in the same pixels through Gamma's pixel form: the sheared
// types within 1e-5 of the peak of the noshear image's floor (the stamp's edge and aliasing,
// measured 8-9e-6), as the pixel-frame operations above.
TEST(MetacalImager, ACutoutsShearIsAppliedOnTheSkyThroughItsJacobian) {
  const int size = 48;
  const double step = 0.01, hlr = 0.55;  // arcsec
  for (const double angle : {0.3, 2.1, -1.2}) {
    const double c = std::cos(angle), s = std::sin(angle), scale = 0.27, g1 = 0.015, g2 = -0.01;
    PixelFrame f;  // J = scale R(angle) [[1 + g1, g2], [g2, 1 - g1]]
    f.dudx = scale * (c * (1 + g1) - s * g2), f.dudy = scale * (c * g2 - s * (1 - g1));
    f.dvdx = scale * (s * (1 + g1) + c * g2), f.dvdy = scale * (s * g2 + c * (1 - g1));
    f.x_ref = f.y_ref = 0.5 * (size - 1);
    const PsfModel psf = moffat(3.0, 3.6, 0.03, -0.02);
    const PsfModel gamma = round_on_sky(3.0, 1.3, f);  // 1.3" = 4.8 px
    SimRenderer::Options opt;
    opt.sersic_indices = {0.5, 1.0};
    SimWorkspace ws;
    auto draw = [&](double e1, double e2, const PsfModel& p) {
      const testing::PixelEllipse q = testing::sky_to_pixel(e1, e2, hlr, 0, 0, f);
      const SimComponent g{0.5, 1000.0, q.radius, q.e1, q.e2, q.x, q.y};
      std::vector<double> out(size * size);
      SimRenderer(p, opt).render({&g, 1}, size, out, ws);
      return out;
    };
    const std::vector<double> observed = draw(0, 0, psf);
    std::string error;
    const auto filters = MetacalFilters::build(psf, gamma, step, MetacalImager::padded_size(size), &error, 1.01, f);
    ASSERT_TRUE(filters) << error;
    EXPECT_NE(filters->inverse_shear(MetacalType::k1p)[1], filters->inverse_shear(MetacalType::k1p)[2]);
    MetacalImager imager(size, filters->period(), FftPlanning::kEstimate);
    std::vector<double> out(kNumMetacalTypes * size * size);
    imager.make_images(observed, *filters, f.x_ref, f.y_ref, out);
    double noshear = 0;
    for (MetacalType t : kMetacalTypes) {
      const auto g = metacal_shear(t, step);
      const std::vector<double> expected = draw(g[0], g[1], gamma);
      const double peak = *std::max_element(expected.begin(), expected.end());
      const double diff =
          max_difference(expected, std::span<const double>(out).subspan(static_cast<int>(t) * size * size, size * size), size) / peak;
      std::printf("angle %+.1f %-7s max |diff| / peak = %.2e\n", angle, metacal_type_name(t), diff);
      if (t == MetacalType::kNoshear) noshear = diff;
      EXPECT_LE(noshear, 2e-5);
      EXPECT_LE(diff, noshear + 1e-5) << metacal_type_name(t);
    }
  }
}

// A reconvolution PSF narrower than the PSF in some direction would amplify noise without bound:
// refused with a message.
TEST(MetacalFilters, AReconvolutionPsfNarrowerThanThePsfIsRefused) {
  std::string error;
  EXPECT_FALSE(MetacalFilters::build(moffat(3.0, 2.85, 0.0, 0.05), moffat(3.0, 2.0, 0.0, 0.0), 0.01, 96, &error));
  EXPECT_NE(error.find("not wider than the PSF"), std::string::npos) << error;
}

// GalSim's metacal reference: the deconvolve-shear-reconvolve of each case's stamp against the
// exactly sheared galaxy convolved with Gamma. Working from the stamp alone loses the light
// outside it; the table printed is docs/metacal.md's. Bound: what the method reaches (measured).
TEST(MetacalImager, GalSimReferenceCases) {
  io::FitsFile f = io::FitsFile::open_read(testing::data_path("galsim-metacal-reference/cases.fits"));
  f.move_to("CASES");
  const double beta = *f.read_key_double("PSFBETA"), fwhm = *f.read_key_double("PSFFWHM");
  const double pe1 = *f.read_key_double("PSFE1"), pe2 = *f.read_key_double("PSFE2");
  const double step = *f.read_key_double("DELTA");
  const double gbeta = *f.read_key_double("GAMBETA"), gfwhm = *f.read_key_double("GAMFWHM");
  const auto dx = f.read_column("dx"), dy = f.read_column("dy"), hlr = f.read_column("hlr"), bf = f.read_column("bulge_frac");
  const int n = static_cast<int>(dx.size());
  const int size = 48;
  const double centre = 0.5 * (size - 1);
  std::string error;
  const auto filters = MetacalFilters::build(moffat(beta, fwhm, pe1, pe2), moffat(gbeta, gfwhm, 0, 0), step,
                                             MetacalImager::padded_size(size), &error);
  ASSERT_TRUE(filters) << error;
  MetacalImager imager(size, filters->period(), FftPlanning::kEstimate);
  std::vector<double> out(kNumMetacalTypes * size * size);
  for (int c = 0; c < n; ++c) {
    char name[32];
    std::snprintf(name, sizeof name, "OBS%02d", c);
    f.move_to(std::string(name));
    const std::vector<double> obs = f.read_image();
    const double cx = centre + dx[c], cy = centre + dy[c];
    imager.make_images(obs, *filters, cx, cy, out);
    for (MetacalType t : kMetacalTypes) {
      std::snprintf(name, sizeof name, "EXACT%02d_%s", c, metacal_type_name(t));
      f.move_to(std::string(name));
      const std::vector<double> exact = f.read_image();
      const double peak = *std::max_element(exact.begin(), exact.end());
      const std::span<const double> ours = std::span<const double>(out).subspan(static_cast<int>(t) * size * size, size * size);
      const double whole = max_difference(exact, ours, size) / peak;
      const double inner = max_difference(exact, ours, size, cx, cy, 8.0) / peak;
      std::printf("case %d hlr %.2f bulge %.2f %-7s whole %.2e  r<8 %.2e\n", c, hlr[c], bf[c], metacal_type_name(t), whole, inner);
      // Measured: inside r < 8, 1.6e-5 (pure disc) to 1.4e-4 (pure bulge); over the stamp up to
      // 1.6e-3 (case 4: hlr 3, bulge 0.7, whose light beyond the stamp is lost).
      EXPECT_LE(inner, 2e-4) << name;
      EXPECT_LE(whole, 2e-3) << name;
    }
  }
}

}  // namespace
}  // namespace stampede
