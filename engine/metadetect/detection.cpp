// The detection filter; see detection.hpp.
#include "engine/metadetect/detection.hpp"

#include <algorithm>
#include <cmath>

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

void filter_detection_image(std::span<const float> image, int width, int height, std::span<const float> filter,
                            std::vector<float>* out, std::vector<float>* rows) {
  // Row by row, each output row summed tap by tap from zero while it sits in L1 (a tap beyond the
  // image adds nothing): the same float sums in the same order whatever the loop order.
  const int n = static_cast<int>(filter.size()), h = n / 2;
  rows->resize(image.size());
  out->resize(image.size());
  float* r = rows->data();
  for (int y = 0; y < height; ++y) {
    const float* in = image.data() + static_cast<std::size_t>(y) * width;
    float* o = r + static_cast<std::size_t>(y) * width;
    std::fill(o, o + width, 0.0f);
    for (int k = 0; k < n; ++k) {
      const float w = filter[k];
      const int shift = k - h;
      const int lo = std::max(0, -shift), hi = std::min(width, width - shift);
      for (int x = lo; x < hi; ++x) o[x] += w * in[x + shift];
    }
  }
  float* o = out->data();
  for (int y = 0; y < height; ++y) {
    float* dst = o + static_cast<std::size_t>(y) * width;
    std::fill(dst, dst + width, 0.0f);
    for (int k = 0; k < n; ++k) {
      const int ys = y + k - h;
      if (ys < 0 || ys >= height) continue;
      const float w = filter[k];
      const float* in = r + static_cast<std::size_t>(ys) * width;
      for (int x = 0; x < width; ++x) dst[x] += w * in[x];
    }
  }
}

}  // namespace stampede
