// What a detector reports for each object, and the detection filter shared by every detector.
#pragma once
#include <span>
#include <vector>

#include "engine/metadetect/metadetect_options.hpp"

namespace stampede {

struct Detection {
  double x = 0, y = 0;  // barycentre of the filtered values (a child's core), 0-based pixels (centres at integers)
  int isophotal_area = 0;  // member pixels above the threshold in the unfiltered image
  int xmin = 0, xmax = 0, ymin = 0, ymax = 0;
  double flux = 0;      // sum of the member pixels of the unfiltered image
  int sep_flags = 0;    // kDetectionMerged | kDetectionTruncated | kDetectionSingular
};

// SEP's object flags, as the table's sep_flags column carries them.
inline constexpr int kDetectionMerged = 0x1;     // a child of a deblended segment
inline constexpr int kDetectionTruncated = 0x2;  // a pixel (a child's core's) on the image's edge
inline constexpr int kDetectionSingular = 0x8;   // x, y moments degenerate: 1/12 added

// The detection filter, a normalised filter_size^2 Gaussian of FWHM filter_fwhm pixels, as its
// 1-D factor (the kernel is their outer product); empty for filter_fwhm 0 (no filtering).
std::vector<float> detection_filter(const DetectionOptions& options);

// out = image convolved with filter (x) filter, zero outside the image (SEP's convolution, done
// separably); rows is scratch.
void filter_detection_image(std::span<const float> image, int width, int height, std::span<const float> filter,
                            std::vector<float>* out, std::vector<float>* rows);

}  // namespace stampede
