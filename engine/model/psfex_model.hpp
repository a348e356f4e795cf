// A PSFEx model (../shared/reference/survey-formats.md): basis images B_k whose polynomial sum in
// the scaled image position gives the PSF anywhere on the image,
//   PSF(x, y) = sum_k c_k B_k,  c_k = xs^i ys^j,  xs = (x - zero_x) / scale_x, ys likewise,
// with k running over (i, j), j = 0..d outer and i = 0..d-j inner (d = 2: 1, x, x^2, y, xy, y^2).
// Positions are SExtractor's X_IMAGE, Y_IMAGE (1-based pixel centres). The result includes the
// pixel response (PSFEx fits stars) and is sampled every `sampling` image pixels, centred on
// sample (nx / 2, ny / 2), integer division, 0-based.
#pragma once

#include <memory>
#include <span>
#include <string>
#include <vector>

#include "engine/model/psf_model.hpp"

namespace stampede {

struct PsfexModel {
  int degree = 0;
  double zero_x = 0, zero_y = 0, scale_x = 1, scale_y = 1;  // POLZERO1/2, POLSCAL1/2
  double sampling = 1;                                      // PSF_SAMP: image pixels per sample
  int nx = 0, ny = 0;                                       // PSFAXIS1, PSFAXIS2
  std::vector<double> basis;  // terms() images of nx * ny, x fastest (the PSF_MASK cube's order)

  static int terms_for_degree(int degree) { return (degree + 1) * (degree + 2) / 2; }
  int terms() const { return terms_for_degree(degree); }
  // What is wrong, naming the PSFEx keyword, or true.
  bool IsValid(std::string* why) const;

  // The polynomial coefficients c_k at (x_image, y_image).
  void coefficients(double x_image, double y_image, std::span<double> c) const;
  // The PSF samples at (x_image, y_image), nx * ny, normalised to unit sum. False, with *error,
  // when the sum is not positive (a model that fails there).
  bool evaluate(double x_image, double y_image, std::span<double> out, std::string* error) const;
  // The same as a PSF image for the renderers (oversampling 1 / sampling, which must be an integer
  // there; pixel-integrated; centred on sample (nx / 2, ny / 2)). Null, with *error, otherwise.
  std::shared_ptr<const PsfImage> image_at(double x_image, double y_image, std::string* error) const;
};

}  // namespace stampede
