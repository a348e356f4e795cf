// Adaptive Gaussian-weighted quadrupole moments of a stamp: the fitter's starting point.
#pragma once

#include <span>

namespace stampede::kernels {

struct ImageMoments {
  bool valid = false;   // false: no positive flux, or the iteration did not give a positive-definite shape
  double flux = 0;      // unweighted sum over unmasked pixels
  double x = 0, y = 0;  // centroid, data-pixel coordinates
  double xx = 0, xy = 0, yy = 0;  // covariance of the matched elliptical Gaussian, pixels^2
  int iterations = 0;
};

// image and mask_weight are size x size row-major; pixels with mask_weight == 0 are ignored.
// The iteration (Bernstein & Jarvis 2002) sets the weight covariance to twice the measured weighted
// covariance until it stops changing, so a Gaussian image returns its own covariance.
ImageMoments adaptive_moments(std::span<const double> image, std::span<const double> mask_weight, int size);

// Reduced-shear ellipticity (a-b)/(a+b) of a covariance matrix.
void covariance_ellipticity(double xx, double xy, double yy, double* e1, double* e2);

}  // namespace stampede::kernels
