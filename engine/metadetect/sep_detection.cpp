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
  const double sigma = options.filter_fwhm / 2.3548200450309493, c = 0.5 * (n - 1);
  std::vector<double> g(static_cast<std::size_t>(n));
  double sum = 0;
  for (int i = 0; i < n; ++i) sum += g[i] = std::exp(-(i - c) * (i - c) / (2 * sigma * sigma));
  std::vector<float> f(static_cast<std::size_t>(n));
  for (int i = 0; i < n; ++i) f[i] = static_cast<float>(g[i] / sum);
  return f;
}

namespace {

// out = image convolved with filter (x) filter, zero outside the image.
void filter_image(std::span<const float> image, int width, int height, std::span<const float> filter,
                  std::vector<float>* out, std::vector<float>* rows) {
  const int n = static_cast<int>(filter.size()), h = n / 2;
  rows->assign(image.size(), 0.0f);
  out->assign(image.size(), 0.0f);
  float* r = rows->data();
  for (int y = 0; y < height; ++y) {
    const float* in = image.data() + static_cast<std::size_t>(y) * width;
    float* o = r + static_cast<std::size_t>(y) * width;
    for (int k = 0; k < n; ++k) {
      const float w = filter[k];
      const int shift = k - h;
      const int lo = std::max(0, -shift), hi = std::min(width, width - shift);
      for (int x = lo; x < hi; ++x) o[x] += w * in[x + shift];
    }
  }
  float* o = out->data();
  for (int k = 0; k < n; ++k) {
    const float w = filter[k];
    const int shift = k - h;
    for (int y = std::max(0, -shift); y < std::min(height, height - shift); ++y) {
      const float* in = r + static_cast<std::size_t>(y + shift) * width;
      float* dst = o + static_cast<std::size_t>(y) * width;
      for (int x = 0; x < width; ++x) dst[x] += w * in[x];
    }
  }
}

}  // namespace

void set_detection_pixel_stack(long long pixels) {
  const auto want = static_cast<std::size_t>(std::max<long long>(pixels, 300000));
  if (sep_get_extract_pixstack() < want) sep_set_extract_pixstack(want);
}

bool detect_objects(std::span<const float> image, int width, int height, double noise_sigma,
                    const DetectionOptions& options, std::span<const float> filter, DetectionScratch* scratch,
                    std::vector<Detection>* out, std::string* error) {
  out->clear();
  if (image.size() != static_cast<std::size_t>(width) * height)
    throw std::invalid_argument("detect_objects: image size does not match width x height");
  if (!(noise_sigma > 0) || !std::isfinite(noise_sigma)) {
    *error = "the image's noise sigma is not positive and finite";
    return false;
  }
  if (!filter.empty()) filter_image(image, width, height, filter, &scratch->filtered, &scratch->rows);
  sep_image im{};
  im.data = filter.empty() ? image.data() : scratch->filtered.data();
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
  out->resize(static_cast<std::size_t>(catalog->nobj));
  for (int i = 0; i < catalog->nobj; ++i) {
    Detection& d = (*out)[static_cast<std::size_t>(i)];
    d.x = catalog->x[i];
    d.y = catalog->y[i];
    d.isophotal_area = catalog->tnpix[i];
    if (!filter.empty()) {
      // SEP was given the filtered image: its x, y are weighted by the filtered values (a deblended
      // child's over its core alone), as SEP with its own filter reports them; flux and isophotal
      // area are of the unfiltered pixels, as SEP takes them. A barycentre of the unfiltered
      // pixels over every member would follow the pixels gathered at random into each child of a
      // blend, which differ between the sheared images (docs/metadetect.md).
      const double thresh = options.threshold * noise_sigma;
      double sum = 0;
      int above = 0;
      for (int k = 0; k < catalog->npix[i]; ++k) {
        const double v = image[static_cast<std::size_t>(catalog->pix[i][k])];
        sum += v;
        above += v > thresh;
      }
      d.isophotal_area = above;
      d.flux = sum;
    }
    d.xmin = catalog->xmin[i], d.xmax = catalog->xmax[i];
    d.ymin = catalog->ymin[i], d.ymax = catalog->ymax[i];
    if (filter.empty()) d.flux = catalog->flux[i];
    d.sep_flags = catalog->flag[i];
  }
  sep_catalog_free(catalog);
  return true;
}

}  // namespace stampede
