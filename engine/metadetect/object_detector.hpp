// Detection on one image as a metadetection run chooses it (DetectionOptions::detector): our
// component-tree detector or SEP, both given the image filtered here. One per thread: it keeps
// every buffer, so steady state allocates nothing (SEP allocates inside its own calls).
#pragma once
#include <span>
#include <string>
#include <vector>

#include "engine/metadetect/component_tree_detector.hpp"
#include "engine/metadetect/detection.hpp"
#include "engine/metadetect/metadetect_options.hpp"

namespace stampede {

class ObjectDetector {
 public:
  explicit ObjectDetector(const DetectionOptions& options);

  // Detects on `image` (width x height, x fastest) whose noise has standard deviation
  // `noise_sigma`: pixels of the filtered image above options.threshold x noise_sigma. False, with
  // *error, where the image cannot be detected on (a non-positive sigma; SEP's failures).
  bool detect(std::span<const float> image, int width, int height, double noise_sigma, std::vector<Detection>* out,
              std::string* error);

 private:
  DetectionOptions options_;
  std::vector<float> filter_, filtered_, rows_;
  ComponentTreeDetector tree_;
};

}  // namespace stampede
