// A source of object indices only: each batch carries the numbers [first, first + count) in its
// records' `id`, and no pixels. For inputs the fit stage reads itself (a MEDS tile: each object's
// cutouts are many, of any size, and each worker thread reads them through its own file handle),
// so the serial reader stage costs nothing and reading runs in parallel with the fits.
#pragma once

#include <algorithm>

#include "engine/pipeline/stamp_batch.hpp"

namespace stampede {

class IndexSource final : public StampSource {
 public:
  explicit IndexSource(long long total) : total_(total) {}
  long long total_objects() const override { return total_; }
  void skip_to(long long index) override { next_ = index; }
  bool fill(StampBatch& batch) override {
    batch.count = static_cast<int>(std::clamp<long long>(total_ - next_, 0, batch.capacity()));
    for (int k = 0; k < batch.count; ++k) {
      batch.records[static_cast<std::size_t>(k)] = ObjectRecord{};
      batch.records[static_cast<std::size_t>(k)].id = next_ + k;
    }
    next_ += batch.count;
    return batch.count > 0;
  }

 private:
  long long total_;
  long long next_ = 0;
};

}  // namespace stampede
