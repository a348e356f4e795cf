// Ring studies and size calibration; see ring_study.hpp.
#include "engine/analysis/ring_study.hpp"

#include <algorithm>
#include <cmath>
#include <complex>
#include <memory>
#include <stdexcept>
#include <vector>

#include "engine/render/renderer_factory.hpp"
#include "engine/render/upsampled_renderer.hpp"
#include "engine/sim/sim_renderer.hpp"
#include "kernels/math/lensing.hpp"
#include "kernels/sersic.hpp"

namespace stampede {
namespace {

double psf_fwhm(const PsfModel& psf) {
  const double fwhm = psf.fwhm();  // NaN for an image
  if (std::isnan(fwhm)) throw std::invalid_argument("size ratio needs an analytic PSF");
  return fwhm;
}

}  // namespace

double convolved_fwhm(const RingGalaxy& galaxy, const PsfModel& psf_in) {
  FftPlanCache plans(FftPlanning::kEstimate);
  // Draw in units of 1/10 pixel so the output "pixels" hardly blur the profile; the centre sits on
  // a pixel centre and the FWHM comes from the profile along +x.
  constexpr double kScale = 10.0;
  PsfModel psf = psf_in;
  psf.moffat.e1 = psf.moffat.e2 = 0.0;  // the definition uses round profiles
  psf.moffat.fwhm *= kScale;
  psf.moffat.truncation *= kScale;
  psf.airy.lambda_over_d *= kScale;
  const double largest = galaxy.disc_radius * std::max(1.0, galaxy.radius_ratio);
  // Light beyond ~8 r_e of the centre adds nothing measurable to the core's FWHM.
  const double extent = 2.0 * (psf_fwhm(psf_in) + 8.0 * largest) * kScale;
  RenderOptions ro;
  ro.stamp_size = 2 * static_cast<int>(extent / 2) + 1;
  ro.upsampling = 1;
  ro.n_central_pixels_to_upsample = 9;
  ro.n_central_pixel_upsampling = 25;
  ro.padding = 0;
  std::string err;
  auto kernel = PsfKernel::build(psf, GridGeometry(ro), plans, &err);
  if (!kernel) throw std::invalid_argument(err);
  UpsampledRenderer renderer(ro, ModelOptions{}, kernel, plans);
  ParamVector p = ParameterSet::default_values();
  const int c = ro.stamp_size / 2;
  const double rd = galaxy.disc_radius * kScale, rb = rd * galaxy.radius_ratio;
  p[index(Param::kX0)] = p[index(Param::kY0)] = c;
  p[index(Param::kE1)] = p[index(Param::kE2)] = 0.0;
  p[index(Param::kRadius)] = rd;
  p[index(Param::kRadiusRatio)] = galaxy.radius_ratio;
  p[index(Param::kBulgeIndex)] = galaxy.bulge_index;
  p[index(Param::kDiscIndex)] = galaxy.disc_index;
  p[index(Param::kBulgeA)] = galaxy.bulge_fraction / kernels::sersic_flux_per_amplitude(rb, galaxy.bulge_index);
  p[index(Param::kDiscA)] = (1 - galaxy.bulge_fraction) / kernels::sersic_flux_per_amplitude(rd, galaxy.disc_index);
  std::vector<double> img(static_cast<std::size_t>(ro.stamp_size) * ro.stamp_size);
  renderer.render(p, img);
  const double* row = img.data() + static_cast<std::size_t>(c) * ro.stamp_size;
  const double half = 0.5 * row[c];
  for (int i = c; i + 1 < ro.stamp_size; ++i)
    if (row[i + 1] < half) return 2.0 * (i - c + (row[i] - half) / (row[i] - row[i + 1])) / kScale;
  throw std::runtime_error("convolved_fwhm: profile does not fall to half maximum on the grid");
}

double disc_radius_for_size_ratio(RingGalaxy galaxy, double ratio, const PsfModel& psf) {
  const double target = ratio * psf_fwhm(psf);
  auto below = [&](double radius) {
    galaxy.disc_radius = radius;
    return convolved_fwhm(galaxy, psf) < target;
  };
  constexpr double kLow = 0.01, kHigh = 20.0;
  constexpr int kIterations = 40;
  // The bisection below, while every midpoint is at or above the target, halves towards kLow
  // through chain[0], chain[1], ...; the first of them below the target (found by bisecting the
  // chain, from its cheap small end) tells every earlier one's outcome without drawing them.
  std::vector<double> chain;
  for (double hi = kHigh; static_cast<int>(chain.size()) < kIterations;) {
    hi = 0.5 * (kLow + hi);
    chain.push_back(hi);
    if (hi - kLow < 1e-4 * kLow) break;
  }
  std::size_t first_below = 0, end = chain.size();  // chain[< first_below] at or above, chain[>= end] below
  while (first_below < end) {
    const std::size_t mid = (first_below + end) / 2;
    if (below(chain[mid])) {
      end = mid;
    } else {
      first_below = mid + 1;
    }
  }
  if (first_below == 0 && below(kHigh))
    throw std::invalid_argument("size ratio " + std::to_string(ratio) + " needs a disc radius above 20 px");
  double lo = kLow, hi = kHigh;
  for (int it = 0; it < kIterations; ++it) {
    const double mid = 0.5 * (lo + hi);
    const auto k = static_cast<std::size_t>(it);
    // Iteration it < first_below is chain[it], known at or above; iteration first_below is known below.
    const bool is_below = k < first_below ? false : (k == first_below && k < chain.size()) || below(mid);
    (is_below ? lo : hi) = mid;
    if (hi - lo < 1e-4 * lo) break;
  }
  return 0.5 * (lo + hi);
}

double half_light_radius_for_size_ratio(double n, double ratio, const PsfModel& psf) {
  RingGalaxy g;
  g.bulge_fraction = 1.0;
  g.bulge_index = n;
  return disc_radius_for_size_ratio(g, ratio, psf);
}

RingStudyResult run_ring_study(const RingStudyConfig& cfg, FftPlanCache& plans) {
  const int s = cfg.fit.render.stamp_size;
  RenderOptions truth_ro;
  truth_ro.stamp_size = s;
  truth_ro.upsampling = cfg.truth_upsampling;
  truth_ro.n_central_pixels_to_upsample = cfg.truth_central;
  truth_ro.n_central_pixel_upsampling = cfg.truth_central_upsampling;
  truth_ro.padding = cfg.truth_padding;
  std::string err;
  auto truth_psf = PsfKernel::build(cfg.psf, GridGeometry(truth_ro), plans, &err);
  auto fit_psf = make_renderer(cfg.fit.renderer, cfg.fit.render, cfg.fit.model, plans)->prepare_psf(cfg.psf, &err);
  if (!truth_psf || !fit_psf) throw std::invalid_argument("ring test PSF: " + err);
  UpsampledRenderer truth(truth_ro, ModelOptions{}, truth_psf, plans);
  std::unique_ptr<SimRenderer> sim;
  SimWorkspace sim_workspace;
  if (cfg.truth == RingStudyConfig::Truth::kSimulator) {
    SimRenderer::Options so;
    so.sersic_indices = {1.0, cfg.galaxy.bulge_index};
    so.max_half_light_radius = std::max(10.0, 2 * cfg.galaxy.disc_radius * std::max(1.0, cfg.galaxy.radius_ratio));
    sim = std::make_unique<SimRenderer>(cfg.psf, so);
  }
  Fitter fitter(cfg.fit, fit_psf, plans);
  const std::size_t npix = static_cast<std::size_t>(s) * s;
  std::vector<double> image(npix), part(npix);
  const RingGalaxy& g = cfg.galaxy;
  const double rd = g.disc_radius, rb = rd * g.radius_ratio;
  const double ab = g.flux * g.bulge_fraction / kernels::sersic_flux_per_amplitude(rb, g.bulge_index);
  const double ad = g.flux * (1 - g.bulge_fraction) / kernels::sersic_flux_per_amplitude(rd, g.disc_index);
  RingStudyResult res;
  std::complex<double> mean[2] = {0, 0};
  for (int sign = 0; sign < 2; ++sign) {
    const std::complex<double> shear(sign == 0 ? cfg.shear1 : -cfg.shear1, sign == 0 ? cfg.shear2 : -cfg.shear2);
    for (int a = 0; a < cfg.n_angles; ++a) {
      const double theta = M_PI * a / cfg.n_angles;
      auto sheared = [&](double magnitude) {
        const std::complex<double> e_int = std::polar(magnitude, 2.0 * theta);
        return kernels::lens_ellipticity(e_int, shear);
      };
      // Each component drawn alone (the other's amplitude 0), then summed.
      std::fill(image.begin(), image.end(), 0.0);
      for (int component = 0; component < 2; ++component) {
        const bool bulge = component == 0;
        if ((bulge ? ab : ad) == 0.0) continue;
        const std::complex<double> e = sheared(bulge ? g.disc_e + g.delta_e : g.disc_e);
        ParamVector p = ParameterSet::default_values();
        p[index(Param::kX0)] = p[index(Param::kY0)] = 0.5 * (s - 1);
        p[index(Param::kE1)] = e.real();
        p[index(Param::kE2)] = e.imag();
        p[index(Param::kRadius)] = bulge ? rb : rd;
        p[index(Param::kBulgeIndex)] = g.bulge_index;
        p[index(Param::kDiscIndex)] = g.disc_index;
        p[index(Param::kBulgeA)] = bulge ? ab : 0.0;
        p[index(Param::kDiscA)] = bulge ? 0.0 : ad;
        if (sim) {
          SimComponent c;
          c.sersic_n = bulge ? g.bulge_index : g.disc_index;
          c.flux = g.flux * (bulge ? g.bulge_fraction : 1 - g.bulge_fraction);
          c.half_light_radius = bulge ? rb : rd;
          c.e1 = e.real();
          c.e2 = e.imag();
          c.x = c.y = 0.5 * (s - 1);
          sim->render(std::span<const SimComponent>(&c, 1), s, part, sim_workspace);
        } else {
          truth.render(p, part);
        }
        for (std::size_t i = 0; i < npix; ++i) image[i] += part[i];
      }
      const FitResult f = fitter.fit(image);
      ++res.fits;
      if (f.status != FitStatus::kOk) ++res.failed;
      mean[sign] += std::complex<double>(f.params[index(Param::kE1)], f.params[index(Param::kE2)]) / double(cfg.n_angles);
    }
  }
  const std::complex<double> diff = mean[0] - mean[1], sum = mean[0] + mean[1];
  res.m1 = diff.real() / (2 * cfg.shear1) - 1;
  res.m2 = diff.imag() / (2 * cfg.shear2) - 1;
  res.c1 = sum.real() / 2;
  res.c2 = sum.imag() / 2;
  return res;
}

}  // namespace stampede
