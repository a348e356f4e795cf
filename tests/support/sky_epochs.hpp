// Cutouts of a galaxy on the sky for joint-fit tests (engine/fit): DES-like random frames, Moffat
// PSFs, and the galaxy drawn in a cutout's pixels by the simulator through sky_to_pixel (an
// independent derivation of the frame), with its sky parameters for the fitter.
#pragma once

#include <cmath>
#include <random>
#include <stdexcept>
#include <string>
#include <vector>

#include "engine/fit/object_fitter.hpp"
#include "engine/sim/sim_renderer.hpp"
#include "support/sky_to_pixel.hpp"

namespace stampede::testing {

inline constexpr int kEpochBox = 48;

inline FitterOptions exact_fit_options() {
  FitterOptions o;
  o.renderer = RendererKind::kExact;
  return o;
}

inline PsfModel moffat_psf(double fwhm, double e1, double e2) {
  PsfModel p;
  p.kind = PsfKind::kMoffat;
  p.moffat = {3.0, fwhm, e1, e2, 0.0};
  return p;
}

struct SkyGalaxy {
  double e1, e2, radius, u0, v0, bulge_flux, disc_flux;
};

struct SkyEpoch {
  PixelFrame frame;
  PsfModel psf;
  std::vector<double> pixels, weight;
  double flux_scale = 1;  // data = flux_scale x model (Observation::flux_scale)
};

// A DES-like frame: 0.263"/px within +-3 %, any rotation, a WCS shear within +-0.02, the object
// within a pixel of the box centre.
inline PixelFrame random_frame(std::mt19937& rng) {
  std::uniform_real_distribution<double> u(-1, 1);
  const double angle = M_PI * u(rng), scale = 0.263 * (1 + 0.03 * u(rng)), g1 = 0.02 * u(rng), g2 = 0.02 * u(rng);
  const double c = std::cos(angle), s = std::sin(angle);
  // J = scale R(angle) [[1 + g1, g2], [g2, 1 - g1]]
  PixelFrame f;
  f.dudx = scale * (c * (1 + g1) - s * g2), f.dudy = scale * (c * g2 - s * (1 - g1));
  f.dvdx = scale * (s * (1 + g1) + c * g2), f.dvdy = scale * (s * g2 + c * (1 - g1));
  f.x_ref = 23.5 + 0.5 * u(rng), f.y_ref = 23.5 + 0.5 * u(rng);
  return f;
}

// The galaxy in the epoch's pixels, drawn by the simulator (exact pixel integrals through the PSF).
inline std::vector<double> draw(const SkyGalaxy& g, const PixelFrame& f, const PsfModel& psf) {
  const PixelEllipse e = sky_to_pixel(g.e1, g.e2, g.radius, g.u0, g.v0, f);
  SimRenderer sim(psf, SimRenderer::Options{});
  const SimComponent parts[2] = {{4.0, g.bulge_flux, e.radius, e.e1, e.e2, e.x, e.y},
                                 {1.0, g.disc_flux, e.radius, e.e1, e.e2, e.x, e.y}};
  std::vector<double> out(kEpochBox * kEpochBox);
  SimWorkspace ws;
  sim.render(parts, kEpochBox, out, ws);
  return out;
}

// Sky parameters of g for the fitter (amplitudes from the fluxes through the renderer's own
// flux per amplitude).
inline ParamVector sky_params(const SkyGalaxy& g, Renderer& r) {
  ParamVector p = ParameterSet::default_values();
  p[index(Param::kX0)] = g.u0, p[index(Param::kY0)] = g.v0;
  p[index(Param::kE1)] = g.e1, p[index(Param::kE2)] = g.e2, p[index(Param::kRadius)] = g.radius;
  p[index(Param::kBulgeA)] = 1, p[index(Param::kDiscA)] = 1;
  double fb = 0, fd = 0;
  r.component_fluxes(p, &fb, &fd);
  p[index(Param::kBulgeA)] = g.bulge_flux / fb, p[index(Param::kDiscA)] = g.disc_flux / fd;
  return p;
}

// The epochs as a fit takes them, their PSFs prepared by `renderer` (one of kEpochBox pixels).
inline std::vector<Observation> epoch_data(Renderer& renderer, std::vector<SkyEpoch>& epochs, int band = 0) {
  std::vector<Observation> data;
  for (SkyEpoch& e : epochs) {
    std::string error;
    auto psf = renderer.prepare_psf(e.psf, &error);
    if (!psf) throw std::runtime_error(error);
    data.push_back({e.pixels, e.weight, kEpochBox, e.frame, psf, e.flux_scale, band});
  }
  return data;
}

// A fit of n_bands bands with each band's part (ObjectFitter::fit into a MultiBandFitResult).
inline MultiBandFitResult fit_bands(ObjectFitter& fitter, std::span<const Observation> data, int n_bands) {
  MultiBandFitResult r;
  r.bands.resize(static_cast<std::size_t>(n_bands));
  r.fit = fitter.fit(data, n_bands, r.bands);
  return r;
}

}  // namespace stampede::testing
