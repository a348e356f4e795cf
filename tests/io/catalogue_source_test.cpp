// CatalogueStampSource on its own: a position however far from the image, or not finite, gives an
// edge-flagged record with no data and no undefined behaviour (run under -fsanitize=undefined:
// |x| >= 9.2e18 used to overflow a long); 64-bit ids are read exactly; the stamps are masks.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <fstream>
#include <limits>
#include <string>
#include <vector>

#include "io/catalogue_source.hpp"
#include "io/fits_file.hpp"
#include "io/text_lines.hpp"
#include "support/scratch_dir.hpp"

namespace {

using namespace stampede;

TEST(CatalogueSource, AnyPositionGivesAFlaggedRecordWithoutOverflow) {
  stampede::testing::ScratchDir scratch("stampede_catalogue_source_");
  {
    io::FitsFile image = io::FitsFile::create(scratch.path("image.fits"), true);
    image.write_image(30, 20, std::vector<double>(600, 1.0));
  }
  const double inf = std::numeric_limits<double>::infinity(), big = std::numeric_limits<double>::max();
  const std::vector<std::pair<double, double>> far = {
      {9.2e18, 5},  {-9.2e18, 5}, {9.3e18, 5}, {5, -9.3e18}, {1e300, 5}, {5, -1e300}, {big, big}, {-big, 5},
      {inf, 5},     {5, -inf},    {NAN, 5},    {5, NAN},     {-40, 5},   {5, 61},     {1e19, 1e19}};
  {
    std::ofstream cat(scratch.path("cat.txt"));
    cat.precision(17);
    for (std::size_t i = 0; i < far.size(); ++i) cat << i << " " << far[i].first << " " << far[i].second << "\n";
    cat << "9223372036854775807 15 10\n";  // INT64_MAX, in the image
  }
  io::CatalogueStampSource source(scratch.path("image.fits"), "", scratch.path("cat.txt"), 9, io::CatalogueColumns{});
  ASSERT_EQ(source.total_objects(), static_cast<long long>(far.size() + 1));
  StampBatch batch(64);
  ASSERT_TRUE(source.fill(batch));
  ASSERT_EQ(batch.count, source.total_objects());
  const ObservationArena& stamps = batch.observations;
  for (int k = 0; k < batch.count; ++k) {  // no weight map: the image edge masks the stamp
    EXPECT_TRUE(stamps.first_of(k).weighted);
    EXPECT_EQ(stamps.first_of(k).weight_kind, WeightKind::kMask);
  }
  for (std::size_t i = 0; i < far.size(); ++i) {
    const ObjectRecord& r = batch.records[i];
    EXPECT_EQ(r.id, static_cast<std::int64_t>(i));
    EXPECT_TRUE(r.flags & kFlagEdge) << far[i].first << ", " << far[i].second;
    double weight = 0;
    for (double w : stamps.weights(stamps.first_of(static_cast<int>(i)))) weight += w;
    EXPECT_EQ(weight, 0.0) << "nothing of the image is in the stamp";
  }
  const ObjectRecord& inside = batch.records[far.size()];
  EXPECT_EQ(inside.id, std::numeric_limits<std::int64_t>::max());
  EXPECT_EQ(inside.flags & kFlagEdge, 0u);
  EXPECT_EQ(stamps.weights(stamps.first_of(static_cast<int>(far.size())))[40], 1.0);
}

// Found by the Python argument fuzzer: a "text catalogue" with no newline (/dev/zero, or a binary
// file named by mistake) made getline grow its line until memory ran out: now an error at 16 MiB.
TEST(CatalogueSource, ATextCatalogueWithoutLineEndsIsAnErrorNotAHang) {
  stampede::testing::ScratchDir scratch("stampede_catalogue_source_");
  {
    io::FitsFile image = io::FitsFile::create(scratch.path("image.fits"), true);
    image.write_image(30, 20, std::vector<double>(600, 1.0));
  }
  std::ofstream(scratch.path("long.txt")) << "1 2 3 " << std::string(io::kMaxTextLine, '7') << "\n";
  for (const std::string& cat : {std::string("/dev/zero"), scratch.path("long.txt")}) {
    try {
      io::CatalogueStampSource source(scratch.path("image.fits"), "", cat, 9, io::CatalogueColumns{});
      ADD_FAILURE() << cat << " was read as a catalogue";
    } catch (const std::runtime_error& e) {
      EXPECT_NE(std::string(e.what()).find(cat + ":1: a line longer than 16777216 bytes: not a text catalogue"),
                std::string::npos) << e.what();
    }
  }
}

}  // namespace
