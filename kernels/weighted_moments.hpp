// Moments under a fixed round Gaussian weight (DES Y6 metadetection's "wmom"): a shape estimator
// with no model and no PSF correction, for metacalibration, which calibrates whatever it measures.
// The weight's width is fixed, not matched to the object, so the estimator is a smooth function of
// the pixels: its shear response has no tail from fits that end at the ellipticity limit.
#pragma once

#include <span>

namespace stampede::kernels {

struct WeightedMoments {
  bool valid = false;        // false: no positive weighted flux or size, |e| >= 1, or the centroid left the stamp
  double x = 0, y = 0;       // the weighted centroid the moments are taken about, pixels
  double flux = 0;           // sum w I
  double t = 0;              // T = Mxx + Myy of the weighted, flux-normalised moments, pixels^2
  double e1 = 0, e2 = 0;     // (Mxx - Myy) / T, 2 Mxy / T
  double e1_err = 0, e2_err = 0, snr = 0;  // for uncorrelated pixel noise of variance `variance`
};

// image is size x size, row-major. The weight is exp(-r^2 / (2 sigma^2)), sigma = fwhm / 2.3548,
// about a centroid found by `centroid_iterations` rounds of the weighted centroid from the stamp's
// centre (so the estimator does not depend on where in the stamp the object is; a fixed count keeps
// it a smooth function of the pixels). variance: each
// pixel's noise variance for the errors and S/N, the noise taken as uncorrelated (metacal's images'
// is not: there they are approximate, as a fit's are); 0 gives errors 0 and snr inf. scratch: at
// least 2 x size values (the weight's row and column factors).
WeightedMoments weighted_moments(std::span<const double> image, int size, double fwhm, double variance,
                                 std::span<double> scratch, int centroid_iterations = 6);

}  // namespace stampede::kernels
