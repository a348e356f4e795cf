// SEP detection; see sep_detection.hpp.
#include "engine/metadetect/sep_detection.hpp"

// sep.h declares C functions without an extern "C" guard.
extern "C" {
#include <sep.h>
}

#include <algorithm>

namespace stampede {

void set_detection_pixel_stack(long long pixels) {
  const auto want = static_cast<std::size_t>(std::max<long long>(pixels, 300000));
  if (sep_get_extract_pixstack() < want) sep_set_extract_pixstack(want);
}

bool sep_detect(std::span<const float> filtered, std::span<const float> raw, int width, int height,
                double noise_sigma, const DetectionOptions& options, std::vector<Detection>* out, std::string* error) {
  out->clear();
  sep_image im{};
  im.data = filtered.data();
  im.dtype = SEP_TFLOAT;
  im.w = width;
  im.h = height;
  im.noiseval = noise_sigma;
  im.noise_type = SEP_NOISE_STDDEV;
  im.gain = 0;
  im.maskthresh = 0;
  sep_catalog* catalog = nullptr;
  const int status = sep_extract(&im, static_cast<float>(options.threshold), SEP_THRESH_REL, options.min_area, nullptr,
                                 0, 0, SEP_FILTER_CONV, options.deblend_thresholds, options.deblend_contrast,
                                 options.clean ? 1 : 0, options.clean_param, &catalog);
  if (status != 0) {
    char message[128] = {0};
    sep_get_errmsg(status, message);
    *error = std::string("SEP extraction failed: ") + message;
    if (catalog) sep_catalog_free(catalog);
    return false;
  }
  const double thresh = options.threshold * noise_sigma;
  out->resize(static_cast<std::size_t>(catalog->nobj));
  for (int i = 0; i < catalog->nobj; ++i) {
    Detection& d = (*out)[static_cast<std::size_t>(i)];
    d.x = catalog->x[i];
    d.y = catalog->y[i];
    // A barycentre of the unfiltered pixels over every member would follow the pixels gathered at
    // random into each child of a blend, which differ between the sheared images
    // (docs/metadetect.md).
    double sum = 0;
    int above = 0;
    for (int k = 0; k < catalog->npix[i]; ++k) {
      const double v = raw[static_cast<std::size_t>(catalog->pix[i][k])];
      sum += v;
      above += v > thresh;
    }
    d.isophotal_area = above;
    d.flux = sum;
    d.xmin = catalog->xmin[i], d.xmax = catalog->xmax[i];
    d.ymin = catalog->ymin[i], d.ymax = catalog->ymax[i];
    d.sep_flags = catalog->flag[i];
  }
  sep_catalog_free(catalog);
  return true;
}

}  // namespace stampede
