// PSFEx models evaluated at image positions; see psfex_model.hpp.
#include "engine/model/psfex_model.hpp"

#include <cmath>

namespace stampede {

bool PsfexModel::IsValid(std::string* why) const {
  auto fail = [&](const std::string& w) {
    if (why) *why = w;
    return false;
  };
  if (degree < 0 || degree > 20) return fail("POLDEG1 = " + std::to_string(degree) + ": must be in [0, 20]");
  if (!(std::isfinite(zero_x) && std::isfinite(zero_y))) return fail("POLZERO1/2 must be finite");
  if (!(std::isfinite(scale_x) && std::isfinite(scale_y) && scale_x != 0 && scale_y != 0))
    return fail("POLSCAL1/2 must be finite and non-zero");
  if (!(sampling > 0 && std::isfinite(sampling))) return fail("PSF_SAMP = " + std::to_string(sampling) + ": must be > 0");
  if (nx < 1 || ny < 1 || nx > 4096 || ny > 4096)
    return fail("PSFAXIS1 x PSFAXIS2 = " + std::to_string(nx) + " x " + std::to_string(ny) + ": must be 1..4096 each");
  if (basis.size() != static_cast<std::size_t>(terms()) * nx * ny)
    return fail("PSF_MASK holds " + std::to_string(basis.size()) + " values, not " + std::to_string(terms()) +
                " basis images of " + std::to_string(nx) + " x " + std::to_string(ny));
  return true;
}

void PsfexModel::coefficients(double x_image, double y_image, std::span<double> c) const {
  const double xs = (x_image - zero_x) / scale_x, ys = (y_image - zero_y) / scale_y;
  std::size_t k = 0;
  double yj = 1;
  for (int j = 0; j <= degree; ++j, yj *= ys) {
    double term = yj;
    for (int i = 0; i + j <= degree; ++i, term *= xs) c[k++] = term;
  }
}

bool PsfexModel::evaluate(double x_image, double y_image, std::span<double> out, std::string* error) const {
  const std::size_t n = static_cast<std::size_t>(nx) * ny;
  std::vector<double> c(static_cast<std::size_t>(terms()));
  coefficients(x_image, y_image, c);
  for (std::size_t p = 0; p < n; ++p) out[p] = 0;
  for (std::size_t k = 0; k < c.size(); ++k) {
    const double* b = basis.data() + k * n;
    for (std::size_t p = 0; p < n; ++p) out[p] += c[k] * b[p];
  }
  double sum = 0;
  for (std::size_t p = 0; p < n; ++p) sum += out[p];
  if (!(sum > 0) || !std::isfinite(sum)) {
    if (error)
      *error = "the PSFEx model sums to " + std::to_string(sum) + " at (X_IMAGE, Y_IMAGE) = (" + std::to_string(x_image) +
               ", " + std::to_string(y_image) + ")";
    return false;
  }
  for (std::size_t p = 0; p < n; ++p) out[p] /= sum;
  return true;
}

std::shared_ptr<const PsfImage> PsfexModel::image_at(double x_image, double y_image, std::string* error) const {
  const double per_pixel = 1 / sampling;
  const long rounded = std::lround(per_pixel);
  if (rounded < 1 || std::abs(per_pixel - rounded) > 1e-9) {
    if (error) *error = "PSF_SAMP = " + std::to_string(sampling) + ": only 1 / integer samplings can be rendered";
    return nullptr;
  }
  auto img = std::make_shared<PsfImage>();
  img->nx = nx;
  img->ny = ny;
  img->pixels.resize(static_cast<std::size_t>(nx) * ny);
  if (!evaluate(x_image, y_image, img->pixels, error)) return nullptr;
  img->centre_x = nx / 2;
  img->centre_y = ny / 2;
  img->oversampling = static_cast<int>(rounded);
  img->pixel_integrated = true;
  return img;
}

}  // namespace stampede
