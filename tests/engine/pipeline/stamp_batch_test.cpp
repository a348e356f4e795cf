// StampBatch's payload: made on first use and kept (a pooled batch reuses it), and a request for
// another type than the batch holds is a logic_error, not a cast into the wrong type.
#include "engine/pipeline/stamp_batch.hpp"

#include <gtest/gtest.h>

#include <stdexcept>
#include <vector>

namespace stampede {
namespace {

struct Rows {
  std::vector<int> values;
};
struct OtherRows {
  double x = 0;
};

TEST(StampBatch, APayloadIsMadeOnceAndAnotherTypeIsRefused) {
  StampBatch batch(4);
  EXPECT_THROW(static_cast<const StampBatch&>(batch).payload<Rows>(), std::logic_error);  // none yet
  Rows& rows = batch.payload<Rows>();
  rows.values = {1, 2, 3};
  EXPECT_EQ(&batch.payload<Rows>(), &rows);
  EXPECT_EQ(static_cast<const StampBatch&>(batch).payload<Rows>().values.size(), 3u);
  EXPECT_THROW(batch.payload<OtherRows>(), std::logic_error);
  batch.begin(10);  // a new fill keeps the payload's storage
  EXPECT_EQ(&batch.payload<Rows>(), &rows);
}

}  // namespace
}  // namespace stampede
