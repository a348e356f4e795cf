// Object detection on one image with SEP (the C library of Source Extractor's algorithms, Debian's
// libsep-dev): thresholding of the filtered image, deblending, cleaning. SEP >= 1.2 keeps its
// working state per thread, so independent images may be detected concurrently; its pixel-stack
// size is global (set_detection_pixel_stack, once, before threads start).
#pragma once
#include <span>
#include <string>
#include <vector>

#include "engine/metadetect/metadetect_options.hpp"

namespace stampede {

struct Detection {
  double x = 0, y = 0;  // barycentre of the filtered values (a child's core), 0-based pixels (centres at integers)
  int isophotal_area = 0;  // pixels above the threshold (unfiltered)
  int xmin = 0, xmax = 0, ymin = 0, ymax = 0;
  double flux = 0;      // sum of the isophotal pixels
  int sep_flags = 0;    // SEP_OBJ_* (merged by deblending, truncated at the edge, ...)
};

// The detection filter, a normalised filter_size^2 Gaussian of FWHM filter_fwhm pixels, as its
// 1-D factor (the kernel is their outer product); empty for filter_fwhm 0 (no filtering).
std::vector<float> detection_filter(const DetectionOptions& options);

// SEP's pixel stack must hold every pixel of an image above the threshold: at least `pixels`.
// Global in SEP: call before detections run on other threads.
void set_detection_pixel_stack(long long pixels);

// detect_objects' buffers, kept by the caller so that steady state allocates nothing.
struct DetectionScratch {
  std::vector<float> filtered, rows;
};

// Detects on `image` (width x height, row-major, x fastest) whose noise has standard deviation
// `noise_sigma` per pixel: pixels of the filtered image above options.threshold x noise_sigma, as
// SEP's extraction with a convolution filter does. The filtering is done here, separably (SEP's
// own 2-D convolution is half of its time), and SEP extracts from the filtered image: its
// barycentre is weighted by the filtered values (a deblended child's over its core), as SEP with
// its own filter gives it; each object's flux and isophotal area are then taken from the
// unfiltered pixels of its segment, as SEP takes them. `filter` from detection_filter. False, with *error from SEP's message, when SEP fails (e.g. the pixel stack is full);
// `out` is replaced.
bool detect_objects(std::span<const float> image, int width, int height, double noise_sigma,
                    const DetectionOptions& options, std::span<const float> filter, DetectionScratch* scratch,
                    std::vector<Detection>* out, std::string* error);

}  // namespace stampede
