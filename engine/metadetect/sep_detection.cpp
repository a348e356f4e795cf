// SEP detection; see sep_detection.hpp.
#include "engine/metadetect/sep_detection.hpp"

// sep.h declares C functions without an extern "C" guard.
extern "C" {
#include <sep.h>
}

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace stampede {

std::vector<float> detection_filter(const DetectionOptions& options) {
  if (options.filter_fwhm <= 0) return {};
  const int n = options.filter_size;
  const double sigma = options.filter_fwhm / 2.3548200450309493;
  std::vector<float> f(static_cast<std::size_t>(n) * n);
  const double c = 0.5 * (n - 1);
  double sum = 0;
  for (int y = 0; y < n; ++y)
    for (int x = 0; x < n; ++x) sum += std::exp(-((x - c) * (x - c) + (y - c) * (y - c)) / (2 * sigma * sigma));
  for (int y = 0; y < n; ++y)
    for (int x = 0; x < n; ++x)
      f[static_cast<std::size_t>(y) * n + x] =
          static_cast<float>(std::exp(-((x - c) * (x - c) + (y - c) * (y - c)) / (2 * sigma * sigma)) / sum);
  return f;
}

void set_detection_pixel_stack(long long pixels) {
  const auto want = static_cast<std::size_t>(std::max<long long>(pixels, 300000));
  if (sep_get_extract_pixstack() < want) sep_set_extract_pixstack(want);
}

bool detect_objects(std::span<const float> image, int width, int height, double noise_sigma,
                    const DetectionOptions& options, std::span<const float> filter, std::vector<Detection>* out,
                    std::string* error) {
  out->clear();
  if (image.size() != static_cast<std::size_t>(width) * height)
    throw std::invalid_argument("detect_objects: image size does not match width x height");
  if (!(noise_sigma > 0) || !std::isfinite(noise_sigma)) {
    *error = "the image's noise sigma is not positive and finite";
    return false;
  }
  sep_image im{};
  im.data = image.data();
  im.dtype = SEP_TFLOAT;
  im.w = width;
  im.h = height;
  im.noiseval = noise_sigma;
  im.noise_type = SEP_NOISE_STDDEV;
  im.gain = 0;
  im.maskthresh = 0;
  sep_catalog* catalog = nullptr;
  const int n = options.filter_size;
  const int status = sep_extract(&im, static_cast<float>(options.threshold), SEP_THRESH_REL, options.min_area,
                                 filter.empty() ? nullptr : filter.data(), filter.empty() ? 0 : n,
                                 filter.empty() ? 0 : n, SEP_FILTER_CONV, options.deblend_thresholds,
                                 options.deblend_contrast, options.clean ? 1 : 0, options.clean_param, &catalog);
  if (status != 0) {
    char message[128] = {0};
    sep_get_errmsg(status, message);
    *error = std::string("SEP extraction failed: ") + message;
    if (catalog) sep_catalog_free(catalog);
    return false;
  }
  out->resize(static_cast<std::size_t>(catalog->nobj));
  for (int i = 0; i < catalog->nobj; ++i) {
    Detection& d = (*out)[static_cast<std::size_t>(i)];
    d.x = catalog->x[i];
    d.y = catalog->y[i];
    d.isophotal_area = catalog->tnpix[i];
    d.xmin = catalog->xmin[i], d.xmax = catalog->xmax[i];
    d.ymin = catalog->ymin[i], d.ymax = catalog->ymax[i];
    d.flux = catalog->flux[i];
    d.sep_flags = catalog->flag[i];
  }
  sep_catalog_free(catalog);
  return true;
}

}  // namespace stampede
