// Moments under a fixed round Gaussian weight (DES Y6 metadetection's "wmom"): a shape estimator
// with no model and no PSF correction, for metacalibration, which calibrates whatever it measures.
// The weight's width is fixed, not matched to the object, so the estimator is a smooth function of
// the pixels: its shear response has no tail from fits that end at the ellipticity limit.
//
// An object seen in several stamps (a MEDS tile's epochs, each with its own WCS) is measured on
// the sky: the weight is round in the sky's (u, v) axes, each stamp's weighted sums are integrals
// over the sky (pixel values over the stamp's flux scale), and the stamps' sums are averaged with
// weights of their inverse noise variance per unit sky area, so the one shape is the combination.
#pragma once

#include <cmath>
#include <span>
#include <vector>

namespace stampede::kernels {

struct WeightedMoments {
  bool valid = false;        // false: no positive weighted flux or size, |e| >= 1, or the centroid left a stamp
  double x = 0, y = 0;       // the weighted centroid the moments are taken about, sky (u, v) (one stamp: pixels)
  double flux = 0;           // sum w I (in sky units: over the stamps' flux scales)
  double t = 0;              // T = Muu + Mvv of the weighted, flux-normalised moments, sky units^2
  double e1 = 0, e2 = 0;     // (Muu - Mvv) / T, 2 Muv / T
  double e1_err = 0, e2_err = 0, snr = 0;  // for each stamp's noise: its covariance, else white of its variance
};

// The noise covariance C of a stamp whose pixels' noise is correlated (metacal's images: the data's
// noise deconvolved, sheared and reconvolved). The moments are linear in the pixels to first order,
// so their errors need only Var(sum_p a_p I_p) = a^T C a for the maps a of their derivatives.
class PixelCovariance {
 public:
  virtual ~PixelCovariance() = default;
  // a: size x size, row-major, the stamp's layout. Called three times per stamp and measurement.
  virtual double variance(std::span<const double> a) = 0;
};

// One stamp of the object: pixel (x, y) (x the column, 0-based, pixel centres at integers) lies at
// sky offset (u, v) = J (x - x_ref, y - y_ref).
struct MomentsStamp {
  std::span<const double> image;  // size x size, row-major
  int size = 0;
  double dudx = 1, dudy = 0, dvdx = 0, dvdy = 1;
  double x_ref = 0, y_ref = 0;
  double flux_scale = 1;  // image = flux_scale x the sky's flux
  double variance = 0;    // each pixel's noise variance; 0 for noise-free (errors 0, snr inf)
  // Correlated noise: its covariance (variance then only weighs the stamps, not the errors); null:
  // white noise of `variance`.
  PixelCovariance* covariance = nullptr;
  // The first stamp's: where the weight's centre starts, in its pixels (a detection's position);
  // NaN: the stamp's centre.
  double start_x = NAN, start_y = NAN;
};

// The weight is exp(-r^2 / (2 sigma^2)) on the sky, sigma = fwhm / 2.3548, about a centroid found by
// `centroid_iterations` Newton steps of the weighted centroid from the first stamp's start (its
// centre unless start_x, start_y say otherwise; 0 steps: the weight stays there) (so the
// estimator does not depend on where in the stamps the object is; a fixed count keeps it a smooth
// function of the pixels). Stamps are averaged with weights flux_scale^2 |det J| / variance (equal
// weights when any variance is 0). The errors take each stamp's noise as white of its variance,
// or as its covariance where it has one (linear propagation, the centroid held). scratch grows to
// what is needed and is kept, so a caller that reuses it allocates nothing in steady state.
WeightedMoments weighted_moments(std::span<const MomentsStamp> stamps, double fwhm, std::vector<double>& scratch,
                                 int centroid_iterations = 6);

// One stamp in its own pixels (J the unit matrix, reference at pixel (0, 0), flux scale 1): the
// centroid in pixel coordinates. scratch: at least 2 x size values.
WeightedMoments weighted_moments(std::span<const double> image, int size, double fwhm, double variance,
                                 std::span<double> scratch, int centroid_iterations = 6, double start_x = NAN,
                                 double start_y = NAN);

}  // namespace stampede::kernels
