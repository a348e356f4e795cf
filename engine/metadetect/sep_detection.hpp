// Object detection with SEP (the C library of Source Extractor's algorithms, Debian's libsep-dev),
// kept for comparison with our own detector (`--detector sep`). SEP >= 1.2 keeps its working
// state per thread, so independent images may be detected concurrently; its pixel-stack size is
// global (set_detection_pixel_stack, once, before threads start).
#pragma once
#include <span>
#include <string>
#include <vector>

#include "engine/metadetect/detection.hpp"
#include "engine/metadetect/metadetect_options.hpp"

namespace stampede {

// SEP's pixel stack must hold every pixel of an image above the threshold: at least `pixels`.
// Global in SEP: call before detections run on other threads.
void set_detection_pixel_stack(long long pixels);

// SEP's extraction from `filtered` (the detection image, already filtered: SEP's own 2-D
// convolution is half of its time) at options.threshold x noise_sigma, with no filter of its own:
// its barycentre is weighted by the filtered values (a deblended child's over its core), as SEP
// with its own filter gives it; each object's flux and isophotal area are then taken from `raw`,
// the unfiltered image, over the object's pixels, as SEP takes them. False, with *error from SEP's
// message, when SEP fails (e.g. the pixel stack is full); `out` is replaced.
bool sep_detect(std::span<const float> filtered, std::span<const float> raw, int width, int height,
                double noise_sigma, const DetectionOptions& options, std::vector<Detection>* out, std::string* error);

}  // namespace stampede
