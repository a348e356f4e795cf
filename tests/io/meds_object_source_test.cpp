// Tests for the MEDS source (io/meds_object_source): a batch of the sample tile's objects carries
// each object's four cutouts with their pixels, weights, frames and PSFEx images, and its identity;
// a shard's end stops the reading; uberseg against a hand-built seg map; one tile per band must
// hold the same objects at the same places.
#include "io/meds_object_source.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <numbers>
#include <string>
#include <vector>

#include "engine/pipeline/range_source.hpp"
#include "io/config_error.hpp"
#include "support/meds_edit.hpp"
#include "support/scratch_dir.hpp"

namespace stampede::io {
namespace {

const std::string kSample = std::string(STAMPEDE_DATA_DIR) + "/meds-sample";

TEST(MedsObjectSource, ABatchCarriesEveryObjectsCutoutsAndIdentity) {
  MedsOptions options;
  MedsObjectSource source({kSample + "/meds.fits"}, options, PsfModel{});
  MedsFile meds = MedsFile::open(kSample + "/meds.fits");
  StampBatch batch(5);
  source.skip_to(3);
  ASSERT_TRUE(source.fill(batch));
  ASSERT_EQ(batch.count, 5);
  EXPECT_EQ(batch.first_object, 3);
  const ObservationArena& arena = batch.observations;
  ASSERT_EQ(arena.objects(), 5);
  ASSERT_EQ(arena.bands(), 1);
  for (int k = 0; k < batch.count; ++k) {
    const MedsObject o = meds.object(3 + k);
    EXPECT_EQ(batch.records[static_cast<std::size_t>(k)].id, o.id);
    EXPECT_EQ(batch.records[static_cast<std::size_t>(k)].survey.number, o.number);
    const BandReading& r = arena.reading(k, 0);
    ASSERT_TRUE(r.readable);
    ASSERT_EQ(r.count, 4) << r.problem;
    EXPECT_EQ(r.first, 4 * k);
    EXPECT_EQ(r.pixels_total, 4 * o.box_size * o.box_size);
    for (int c = 0; c < 4; ++c) {
      const ArenaObservation& obs = arena[r.first + c];
      EXPECT_EQ(obs.cutout, c + 1);
      EXPECT_EQ(obs.box_size, o.box_size);
      EXPECT_TRUE(obs.psf_from_image);
      ASSERT_TRUE(obs.psf.image);
      EXPECT_EQ(obs.frame.dudx, o.cutouts[static_cast<std::size_t>(c + 1)].dudcol);
      std::vector<double> want(static_cast<std::size_t>(o.box_size * o.box_size));
      meds.read_cutout(o, c + 1, MedsCutoutType::kImage, want);
      const std::span<const double> got = arena.pixels(obs);
      EXPECT_TRUE(std::equal(want.begin(), want.end(), got.begin())) << "object " << 3 + k << " cutout " << c + 1;
    }
  }
}

TEST(MedsObjectSource, AShardsEndStopsTheReading) {
  MedsOptions options;
  MedsObjectSource source({kSample + "/meds.fits"}, options, PsfModel{});
  RangeSource shard(source, 2, 9);
  StampBatch batch(5);
  ASSERT_TRUE(shard.fill(batch));
  EXPECT_EQ(batch.count, 5);
  ASSERT_TRUE(shard.fill(batch));
  EXPECT_EQ(batch.count, 2);
  EXPECT_EQ(batch.observations.objects(), 2);  // nothing read past the shard's end
  EXPECT_EQ(batch.first_object, 7);
  EXPECT_FALSE(shard.fill(batch));
}

// Band tiles used to be matched by id alone: an r tile whose object lay 1 degree away was fitted with
// the g tile's as one galaxy. An offset beyond kMaxBandOffsetArcsec is refused naming both tiles,
// the object's id and row and the offset; one within it (per-band astrometry) is not.
TEST(MedsObjectSource, BandTilesWhoseObjectsLieApartAreRefused) {
  testing::ScratchDir dir("stampede_meds_source_");
  const std::string g = dir.path("g.fits"), r = dir.path("r.fits");
  std::filesystem::copy_file(kSample + "/meds.fits", g);
  std::filesystem::copy_file(kSample + "/meds.fits", r);
  MedsFile tile = MedsFile::open(g);
  const MedsObject o = tile.object(5);
  const double arcsec = 1.0 / 3600, degree = std::numbers::pi / 180;
  auto refusal = [&]() -> std::string {
    try {
      MedsObjectSource source({g, r}, MedsOptions{}, PsfModel{});
    } catch (const ConfigError& e) {
      return e.what();
    }
    return "";
  };
  // Within the tolerance: 0.6 arcsec in dec, then 0.6 arcsec on the sky in ra (cos dec wider).
  testing::MedsEditor(r).set_cell("object_data", "dec", 5, 0, o.dec + 0.6 * arcsec);
  EXPECT_EQ(refusal(), "");
  testing::MedsEditor(r).set_cell("object_data", "dec", 5, 0, o.dec);
  testing::MedsEditor(r).set_cell("object_data", "ra", 5, 0, o.ra + 0.6 * arcsec / std::cos(o.dec * degree));
  EXPECT_EQ(refusal(), "");
  // 1 degree in ra: refused.
  testing::MedsEditor(r).set_cell("object_data", "ra", 5, 0, o.ra + 1.0);
  const std::string far = refusal();
  for (const std::string& part : {"--meds '" + r + "'", "object id " + std::to_string(o.id) + " (object_data row 5)",
                                  "--meds '" + g + "'", std::string("(within 1 arcsec)")})
    EXPECT_NE(far.find(part), std::string::npos) << part << " in: " << far;
  const std::size_t at = far.find(" deg, ");
  ASSERT_NE(at, std::string::npos) << far;
  const double offset = std::stod(far.substr(at + 6));  // "3600 arcsec from its place ..."
  EXPECT_NEAR(offset, 3600 * std::cos(o.dec * degree), 1.0) << far;  // 1 degree of ra at that dec
  // 1.5 arcsec in dec: refused; a position missing in one tile (NaN) cannot be matched either.
  testing::MedsEditor(r).set_cell("object_data", "ra", 5, 0, o.ra);
  testing::MedsEditor(r).set_cell("object_data", "dec", 5, 0, o.dec - 1.5 * arcsec);
  EXPECT_NE(refusal().find("1.5 arcsec from its place"), std::string::npos) << refusal();
  testing::MedsEditor(r).set_cell("object_data", "dec", 5, 0, NAN);
  EXPECT_NE(refusal().find("nan arcsec from its place"), std::string::npos) << refusal();
}

// Uberseg on a hand-built 6 x 6 seg map: object 5 in the top-left, object 9 in the bottom-right;
// each pixel keeps its weight unless a pixel of 9 is strictly nearer than every pixel of 5.
TEST(MedsObjectSource, UbersegMasksWhatIsNearerAnotherObject) {
  const std::vector<double> seg = {5, 5, 0, 0, 0, 0,  //
                                   5, 5, 0, 0, 0, 0,  //
                                   0, 0, 0, 0, 0, 0,  //
                                   0, 0, 0, 0, 0, 0,  //
                                   0, 0, 0, 0, 9, 9,  //
                                   0, 0, 0, 0, 9, 9};
  // Worked out from squared distances to the nearest 5-pixel and 9-pixel (ties kept): (5, 1): 16
  // against 9, masked; (3, 2): 5 against 5, kept; (5, 0): 16 against 16, kept; (3, 3): 8 against 2.
  const std::vector<double> want = {1, 1, 1, 1, 1, 1,  //
                                    1, 1, 1, 1, 1, 0,  //
                                    1, 1, 1, 1, 0, 0,  //
                                    1, 1, 1, 0, 0, 0,  //
                                    1, 1, 0, 0, 0, 0,  //
                                    1, 0, 0, 0, 0, 0};
  std::vector<double> weight(36, 1.0);
  apply_uberseg(seg, 6, 5, weight);
  for (int i = 0; i < 36; ++i) EXPECT_EQ(weight[i], want[i]) << "pixel (" << i % 6 << ", " << i / 6 << ")";
  std::vector<double> untouched(36, 1.0);
  apply_uberseg(std::vector<double>(36, 0.0), 6, 5, untouched);
  EXPECT_EQ(untouched, std::vector<double>(36, 1.0));
}

}  // namespace
}  // namespace stampede::io
