// A contiguous range [begin, end) of another source's objects, for a job-array shard
// (`stampede fit --shard i/N`): the objects keep their identity (ids, positions) in the whole
// input, so the shards' tables joined in order are the whole run's table.
#pragma once

#include <algorithm>

#include "engine/pipeline/stamp_batch.hpp"

namespace stampede {

class RangeSource final : public StampSource {
 public:
  // `inner` must outlive this; 0 <= begin <= end <= inner.total_objects().
  RangeSource(StampSource& inner, long long begin, long long end) : inner_(inner), begin_(begin), end_(end) {
    inner_.skip_to(begin_);
    inner_.set_end(end_);
  }
  long long total_objects() const override { return end_ - begin_; }
  void skip_to(long long index) override {
    next_ = begin_ + index;
    inner_.skip_to(next_);
  }
  bool fill(StampBatch& batch) override {
    if (next_ >= end_ || !inner_.fill(batch)) return false;
    // The inner source may read past the range's end once, at the last batch: those are dropped.
    batch.count = static_cast<int>(std::min<long long>(batch.count, end_ - next_));
    next_ += batch.count;
    return batch.count > 0;
  }

 private:
  StampSource& inner_;
  long long begin_, end_;
  long long next_ = begin_;
};

// The objects of shard `index` of `count` over `total` objects: [total*index/count,
// total*(index+1)/count), so the shards' sizes differ by at most one and cover every object once.
inline long long shard_begin(long long total, int index, int count) {
  return static_cast<long long>((static_cast<__int128>(total) * index) / count);
}

}  // namespace stampede
