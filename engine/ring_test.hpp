// Noise-free ring tests (Nakajima & Bernstein 2007) as in im3shape section 4: galaxies at N
// orientations, sheared by +g and -g, drawn at high accuracy, fitted, and m, c measured from
//   <e>(+g) - <e>(-g) = 2 (1 + m) g,   <e>(+g) + <e>(-g) = 2 c.
// Also the GREAT08 size definition Rgp/Rp (FWHM of the round galaxy convolved with the PSF, no
// pixel, over the PSF's FWHM) and its inversion to a half-light radius.
#pragma once

#include "engine/fitter.hpp"
#include "engine/psf.hpp"

namespace stampede {

struct RingTestConfig {
  double shear1 = 0.02, shear2 = 0.01;
  int n_angles = 4;                  // orientations over 180 degrees (0, 45, 90, 135 for 4)
  double intrinsic_e = 0.3;          // |e| of every ring member before shear
  double bulge_fraction = 0.5;       // of the total flux
  double half_light_radius = 1.5;    // pixels, both components
  double flux = 1000;
  PsfOptions psf;
  FitterOptions fit;                 // the fitter under test (its stamp_size is the stamp)
  // The truth renderer: well beyond the fitter's defaults.
  int truth_upsampling = 25, truth_central = 25, truth_central_upsampling = 25, truth_padding = 8;
};

struct RingTestResult {
  double m1 = NAN, m2 = NAN, c1 = NAN, c2 = NAN;
  int fits = 0, failed = 0;
};

RingTestResult run_ring_test(const RingTestConfig& config, FftPlanCache& plans);

// FWHM (pixels) of a round Sérsic (n, half-light radius) convolved with the PSF, without pixel.
double convolved_fwhm(double n, double half_light_radius, const PsfOptions& psf, FftPlanCache& plans);
// The half-light radius giving FWHM(gal (x) PSF) / FWHM(PSF) = ratio.
double half_light_radius_for_size_ratio(double n, double ratio, const PsfOptions& psf, FftPlanCache& plans);

}  // namespace stampede
