// Noise-free ring tests (Nakajima & Bernstein 2007) as in im3shape section 4: galaxies at N
// orientations, sheared by +g and -g, drawn at high accuracy, fitted, and m, c measured from
//   <e>(+g) - <e>(-g) = 2 (1 + m) g,   <e>(+g) + <e>(-g) = 2 c.
// Also the GREAT08 size definition Rgp/Rp (FWHM of the round galaxy convolved with the PSF, no
// pixel, over the PSF's FWHM) and its inversion to a half-light radius.
#pragma once

#include "engine/fit/fitter.hpp"
#include "engine/render/psf_kernel.hpp"

namespace stampede {

// The true galaxy of a ring test: a bulge and a disc with their own Sérsic indices and radii,
// sharing the ring member's position angle; each component is sheared on its own, so a bulge
// rounder than its disc (delta_e < 0) stays so after shear.
struct RingGalaxy {
  double bulge_fraction = 0.5;  // of the total flux
  double disc_radius = 1.5;     // half-light radius, pixels
  double radius_ratio = 1.0;    // bulge / disc half-light radius
  double bulge_index = 4.0;
  double disc_index = 1.0;
  double disc_e = 0.3;          // |e| of the disc before shear
  double delta_e = 0.0;         // |e_bulge| - |e_disc| before shear
  double flux = 1000;
};

struct RingStudyConfig {
  double shear1 = 0.02, shear2 = 0.01;
  int n_angles = 4;  // orientations over 180 degrees (0, 45, 90, 135 for 4)
  RingGalaxy galaxy;
  PsfModel psf;
  FitterOptions fit;  // the fitter under test (its stamp_size is the stamp)
  // The truth renderer: the upsampled renderer well beyond the fitter's defaults (the paper's
  // figures), or the simulator's exact pixel integrals (engine/sim/sim_renderer, 1e-6 of GalSim's
  // peak), which a fit by the exact renderer needs: the upsampled truth's own error is ~1e-4.
  enum class Truth { kUpsampled, kSimulator };
  Truth truth = Truth::kUpsampled;
  int truth_upsampling = 25, truth_central = 25, truth_central_upsampling = 25, truth_padding = 8;
};

struct RingStudyResult {
  double m1 = NAN, m2 = NAN, c1 = NAN, c2 = NAN;
  int fits = 0, failed = 0;
};

RingStudyResult run_ring_study(const RingStudyConfig& config, FftPlanCache& plans);

// FWHM (pixels) of the round version of `galaxy` convolved with the round PSF, without pixel.
// Drawn at 0.1 px on a grid of ~16 radii a side, with FFT plans of its own, freed on return: the
// grid is one-off and large (~650 MB of buffers at a 10 px radius).
double convolved_fwhm(const RingGalaxy& galaxy, const PsfModel& psf);
// The disc radius (bulge radius following radius_ratio) giving FWHM(gal (x) PSF) / FWHM(PSF) = ratio.
// Rendered at 0.1 px and bisected to 1e-4 over (0.01, 20) px; the bisection's first halvings from
// 20 px, whose outcome follows from one smaller radius's (the FWHM grows with the radius), are not
// drawn, so memory stays that of ~2x the answer's radius (not 20 px's gigabytes) for the same answer. The simulator's calibration, Great08Simulator::half_light_radius
// (exact transform, 1e-11), is canonical for the GREAT08-like sets and gives 0.1% (disc) to 0.5% (bulge)
// larger radii for the GREAT08 PSF; this one stays because ring studies need what the simulator's
// transforms do not cover (any Sersic index, bulge and disc radii apart, obscured Airy discs).
double disc_radius_for_size_ratio(RingGalaxy galaxy, double ratio, const PsfModel& psf);
// Single-component shorthand: the half-light radius of a Sérsic n with that size ratio.
double half_light_radius_for_size_ratio(double n, double ratio, const PsfModel& psf);

}  // namespace stampede
