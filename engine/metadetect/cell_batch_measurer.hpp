// The pipeline's per-thread task of a metadetection run: each cell of a batch measured by a
// CellMeasurer (its five sheared images, detections and measurements) into the batch's rows; a
// cell the source could not prepare (its PSF failed there) one flagged row.
#pragma once

#include <vector>

#include "engine/metadetect/cell_measurer.hpp"
#include "engine/metadetect/metadetect_options.hpp"
#include "engine/pipeline/pipeline.hpp"

namespace stampede {

class CellBatchMeasurer : public BatchFitter {
 public:
  explicit CellBatchMeasurer(const MetadetectOptions& options) : measurer_(options) {}
  void fit(StampBatch& batch) override;

 private:
  CellMeasurer measurer_;
  std::vector<MetadetectBand> bands_;  // the current cell's, reused
};

}  // namespace stampede
