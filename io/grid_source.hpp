// Stamps from a GREAT08-layout grid image (and an optional weight image of the same shape),
// streamed one row of stamps at a time. Object id = iy * nx + ix.
#pragma once

#include <memory>
#include <string>
#include <vector>

#include "engine/pipeline/stamp_batch.hpp"
#include "io/stamp_grid.hpp"

namespace stampede::io {

class GridStampSource final : public StampSource {
 public:
  // stamp_size <= 0: from the header key STAMPSZ. weight_path "" = no weight map. Throws FitsError
  // naming the file (missing, corrupt, size does not divide, weight shape differs).
  GridStampSource(const std::string& image_path, const std::string& weight_path, int stamp_size);

  int stamp_size() const { return image_.stamp_size(); }
  FitsFile& header() { return image_.file(); }
  long long total_objects() const override { return static_cast<long long>(image_.grid_nx()) * image_.grid_ny(); }
  void skip_to(long long index) override { next_ = index; }
  bool fill(StampBatch& batch) override;

 private:
  StampGridReader image_;
  std::unique_ptr<StampGridReader> weight_;
  std::vector<double> row_, weight_row_;
  int loaded_row_ = -1;
  long long next_ = 0;
};

}  // namespace stampede::io
