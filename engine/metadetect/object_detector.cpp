// Detection on one image; see object_detector.hpp.
#include "engine/metadetect/object_detector.hpp"

#include <cmath>
#include <stdexcept>

#include "engine/metadetect/sep_detection.hpp"

namespace stampede {

ObjectDetector::ObjectDetector(const DetectionOptions& options)
    : options_(options), filter_(detection_filter(options)) {}

bool ObjectDetector::detect(std::span<const float> image, int width, int height, double noise_sigma,
                            std::vector<Detection>* out, std::string* error) {
  out->clear();
  if (image.size() != static_cast<std::size_t>(width) * height)
    throw std::invalid_argument("ObjectDetector::detect: image size does not match width x height");
  if (width <= 0 || height <= 0) {
    *error = "the image has no pixels";
    return false;
  }
  if (!(noise_sigma > 0) || !std::isfinite(noise_sigma)) {
    *error = "the image's noise sigma is not positive and finite";
    return false;
  }
  std::span<const float> filtered = image;
  if (!filter_.empty()) {
    filter_detection_image(image, width, height, filter_, &filtered_, &rows_);
    filtered = filtered_;
  }
  if (options_.detector == DetectorKind::kSep)
    return sep_detect(filtered, image, width, height, noise_sigma, options_, out, error);
  // SEP's relative threshold: the option (a float) times sigma, as a float.
  const float threshold = static_cast<float>(static_cast<double>(static_cast<float>(options_.threshold)) * noise_sigma);
  tree_.detect(filtered, image, width, height, threshold, options_, out);
  return true;
}

}  // namespace stampede
