// Metadetection of one cell (Sheldon et al. 2020): its five metacal images (noshear, 1p, 1m, 2p,
// 2m; fixnoise), detection on each with SEP, and each detection measured on the image it was found
// on with weighted moments under a round Gaussian weight (wmom); or, for comparison, per-object
// metacal at the positions detected on the noshear image (per_object_metacal). One per thread: it owns the FFT
// plans and every buffer, so a run of cells of one size allocates nothing but SEP's own work.
#pragma once
#include <memory>
#include <span>
#include <string>
#include <vector>

#include "engine/common/fftw_support.hpp"
#include "engine/metacal/metacal_filters.hpp"
#include "engine/metacal/metacal_image_set.hpp"
#include "engine/metadetect/metadetect_options.hpp"
#include "engine/metadetect/metadetect_row.hpp"
#include "engine/metadetect/sep_detection.hpp"
#include "engine/model/psf_model.hpp"

namespace stampede {

struct MetadetectCell {
  long long index = 0;  // the cell's number in the run: keys its fixnoise field
  int size = 0;
  std::span<const double> pixels;  // size^2, row-major (x fastest)
  std::span<const double> weight;  // inverse variance; 0 masks
  double origin_x = 0, origin_y = 0;  // the input image's pixel of the cell's (0, 0)
  double pixel_scale = 0;             // arcsec per pixel
  const PsfModel* psf = nullptr;      // in the cell's pixels
  // Detections kept: barycentre, carried back through the image's metacal shear to the unsheared
  // cell, in [keep_x0, keep_x1) x [keep_y0, keep_y1) (cell pixels); the rest belong to a
  // neighbouring cell or to the image's buffer.
  double keep_x0 = 0, keep_x1 = 0, keep_y0 = 0, keep_y1 = 0;
};

class CellMeasurer {
 public:
  explicit CellMeasurer(const MetadetectOptions& options, FftPlanning planning = FftPlanning::kEstimate);
  // Appends the cell's rows (noshear, 1p, 1m, 2p, 2m; detections in SEP's order) to `rows`; a cell
  // that cannot be measured (its PSF gives no bounded metacal filters, SEP fails) appends one row
  // flagged kMetadetectCellFailed and returns false with *problem.
  bool measure(const MetadetectCell& cell, std::vector<MetadetectRow>* rows, std::string* problem);
  // The last cell's reconvolution PSF's T under the weight (pixels^2), for tests.
  double psf_t_pixels() const { return psf_t_; }

 private:
  bool prepare_psf(const PsfModel& psf, double pixel_scale, std::string* problem);
  void measure_image(const MetadetectCell& cell, int type, std::span<const double> image, double variance,
                     std::vector<MetadetectRow>* rows);
  // Whether the cell keeps detection d of image `type` (its unsheared position in the keep region).
  bool owns(const MetadetectCell& cell, int type, const Detection& d) const;
  // The weighted moments of a box x box stamp whose pixel (0, 0) is the cell's (x0, y0) into *r.
  void fill_moments(const MetadetectCell& cell, std::span<const double> stamp, int box, int x0, int y0,
                    double variance, const Detection& d, MetadetectRow* r);
  // options.per_object_metacal: each noshear detection's metacal stamps, five rows each.
  void per_object_rows(const MetadetectCell& cell, std::vector<MetadetectRow>* rows);

  MetadetectOptions options_;
  FftPlanning planning_;
  std::unique_ptr<MetacalImageSet> images_set_;
  std::shared_ptr<const MetacalFilters> filters_;
  PsfModel psf_;
  bool have_psf_ = false;
  double psf_scale_ = 0, psf_t_ = 0, weight_fwhm_px_ = 0;
  std::vector<float> filter_, image_f_;
  DetectionScratch detection_scratch_;
  std::vector<double> images_, stamp_, scratch_;
  std::unique_ptr<MetacalImageSet> stamp_set_;  // per_object_metacal
  std::shared_ptr<const MetacalFilters> stamp_filters_;
  std::vector<double> stamp_images_, stamp_pixels_, stamp_weight_;
  std::vector<Detection> detections_;
};

}  // namespace stampede
