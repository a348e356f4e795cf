// Tests for the MEDS reader (io/meds_file) against the tile the `meds` package itself wrote
// (../shared/data/meds-sample): the layout, every cutout's pixels against its source image, the
// Jacobians against the truth, and each kind of bad file or bad object named as it should be.
#include "io/meds_file.hpp"

#include <fitsio.h>
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <string>
#include <vector>

#include "support/error_assertions.hpp"
#include "support/meds_edit.hpp"
#include "support/scratch_dir.hpp"

namespace stampede::io {
namespace {

using stampede::testing::Contains;
using stampede::testing::error_of;

const std::string kSample = std::string(STAMPEDE_DATA_DIR) + "/meds-sample";
const std::string kMeds = kSample + "/meds.fits";

TEST(MedsFile, ReadsTheSampleTilesLayout) {
  MedsFile m = MedsFile::open(kMeds);
  EXPECT_EQ(m.size(), 24);
  EXPECT_EQ(m.max_cutouts(), 5);
  ASSERT_EQ(m.images().size(), 5u);
  EXPECT_EQ(m.images()[1].image_path, "src/se_e1.fits.fz");
  EXPECT_EQ(m.images()[1].psf_path, "psfex/se_e1.psf");
  EXPECT_EQ(m.images()[0].position_offset, 1.0);
  for (MedsCutoutType t : {MedsCutoutType::kImage, MedsCutoutType::kWeight, MedsCutoutType::kSeg, MedsCutoutType::kBmask})
    EXPECT_EQ(m.array_length(t), 276480) << meds_hdu_name(t);
  EXPECT_FALSE(m.has(MedsCutoutType::kNoise));
  for (long long row = 0; row < m.size(); ++row) {
    const MedsObject o = m.object(row);
    EXPECT_TRUE(o.problem.empty()) << o.problem;
    EXPECT_EQ(o.box_size, 48);
    ASSERT_EQ(o.cutouts.size(), 5u);
    for (const MedsCutout& c : o.cutouts) EXPECT_TRUE(c.problem.empty()) << c.problem;
    // survey-formats.md: cutout_row = orig_row - orig_start_row.
    EXPECT_DOUBLE_EQ(o.cutouts[2].cutout_row, o.cutouts[2].orig_row - o.cutouts[2].orig_start_row);
  }
}

// The truth's CUTOUTS table (rows in object, cutout order) gives the same Jacobians and positions;
// its Jacobians come from GalSim's WCS, which the writer's own check matched to 2e-10 relative.
TEST(MedsFile, JacobiansAndPositionsMatchTheTruth) {
  MedsFile m = MedsFile::open(kMeds);
  FitsFile truth = FitsFile::open_read(kSample + "/truth.fits");
  truth.move_to("CUTOUTS");
  const std::vector<double> dudrow = truth.read_column("dudrow"), dvdcol = truth.read_column("dvdcol"),
                            dudcol = truth.read_column("dudcol"), dvdrow = truth.read_column("dvdrow"),
                            row = truth.read_column("cutout_row"), col = truth.read_column("orig_col");
  std::size_t k = 0;
  for (long long i = 0; i < m.size(); ++i) {
    const MedsObject o = m.object(i);
    for (const MedsCutout& c : o.cutouts) {
      ASSERT_LT(k, dudrow.size());
      EXPECT_NEAR(c.dudrow, dudrow[k], 1e-10);
      EXPECT_NEAR(c.dudcol, dudcol[k], 1e-10);
      EXPECT_NEAR(c.dvdrow, dvdrow[k], 1e-10);
      EXPECT_NEAR(c.dvdcol, dvdcol[k], 1e-10);
      EXPECT_NEAR(c.cutout_row, row[k], 1e-9);
      EXPECT_NEAR(c.orig_col, col[k], 1e-9);
      ++k;
    }
  }
  EXPECT_EQ(k, dudrow.size());
}

// Every image and weight cutout is the box_size^2 region of its source image at
// (orig_start_row, orig_start_col): the flat-array layout and start_row read right.
TEST(MedsFile, CutoutsAreTheirSourceImagesPixels) {
  MedsFile m = MedsFile::open(kMeds);
  std::vector<FitsFile> sci, wgt;
  for (const MedsImageInfo& info : m.images()) {
    sci.push_back(FitsFile::open_read(kSample + "/" + info.image_path + "[SCI]"));
    wgt.push_back(FitsFile::open_read(kSample + "/" + info.image_path + "[WGT]"));
  }
  std::vector<double> cut(48 * 48), src(48 * 48);
  int compared = 0;
  for (long long i = 0; i < m.size(); ++i) {
    const MedsObject o = m.object(i);
    for (int k = 0; k < static_cast<int>(o.cutouts.size()); ++k) {
      const MedsCutout& c = o.cutouts[k];
      const auto f = static_cast<std::size_t>(c.file_id);
      for (int w = 0; w < 2; ++w) {
        m.read_cutout(o, k, w ? MedsCutoutType::kWeight : MedsCutoutType::kImage, cut);
        FitsFile& image = w ? wgt[f] : sci[f];
        const FitsFile::ImageShape s = image.image_shape();
        // Off-chip parts are zero in the cutout; compare the on-chip pixels.
        for (long y = 0; y < 48; ++y)
          for (long x = 0; x < 48; ++x) {
            const long yy = c.orig_start_row + y, xx = c.orig_start_col + x;
            if (yy < 0 || xx < 0 || yy >= s.ny || xx >= s.nx) {
              EXPECT_EQ(cut[y * 48 + x], 0.0);
              continue;
            }
            double v = 0;
            image.read_image_region(xx, yy, 1, 1, std::span<double>(&v, 1));
            ASSERT_EQ(cut[y * 48 + x], v) << "object " << i << " cutout " << k << " pixel (" << x << ", " << y << ")";
          }
        ++compared;
      }
      if (i > 3) break;  // pixel by pixel through CFITSIO is slow: all cutouts of the first objects, then one each
    }
  }
  EXPECT_GT(compared, 40);
}

// Test files: a copy of the sample, edited with CFITSIO.
class BrokenMeds : public ::testing::Test {
 protected:
  stampede::testing::ScratchDir dir{"stampede_meds_"};
  std::string path = dir.path("tile.fits");
  stampede::testing::MedsEditor editor{path};
  void SetUp() override { std::filesystem::copy_file(kMeds, path); }
  template <class V>
  void set_cell(const char* hdu, const char* column, long long row, long long element, V value) {
    editor.set_cell(hdu, column, row, element, value);
  }
};

TEST_F(BrokenMeds, AMissingHduIsNamed) {
  editor.delete_hdu("image_info");
  const std::string e = error_of<FitsError>([&] { MedsFile::open(path); });
  EXPECT_TRUE(Contains(e, "tile.fits")) << e;
  EXPECT_TRUE(Contains(e, "no HDU 'image_info'")) << e;
}

TEST_F(BrokenMeds, AMissingColumnIsNamedWithItsHdu) {
  editor.delete_column("object_data", "dvdcol");
  const std::string e = error_of<FitsError>([&] { MedsFile::open(path); });
  EXPECT_TRUE(Contains(e, "'object_data'")) << e;
  EXPECT_TRUE(Contains(e, "no column 'dvdcol'")) << e;
}

TEST_F(BrokenMeds, ACutoutPastItsArrayIsThatCutoutsProblem) {
  set_cell("object_data", "start_row", 23, 4, 276480LL - 48 * 48 + 1);
  MedsFile m = MedsFile::open(path);
  const MedsObject o = m.object(23);
  EXPECT_TRUE(o.problem.empty());
  EXPECT_TRUE(o.cutouts[3].problem.empty());
  const std::string& p = o.cutouts[4].problem;
  EXPECT_TRUE(Contains(p, "tile.fits")) << p;
  EXPECT_TRUE(Contains(p, "object 23 (id ")) << p;
  EXPECT_TRUE(Contains(p, "'start_row'[4] = 274177")) << p;
  EXPECT_TRUE(Contains(p, "276480 pixels of HDU 'image_cutouts'")) << p;
  std::vector<double> out(48 * 48);
  EXPECT_THROW(m.read_cutout(o, 4, MedsCutoutType::kImage, out), FitsError);
}

TEST_F(BrokenMeds, AZeroBoxSizeIsTheObjectsProblem) {
  set_cell("object_data", "box_size", 5, 0, 0LL);
  MedsFile m = MedsFile::open(path);
  const MedsObject o = m.object(5);
  EXPECT_TRUE(Contains(o.problem, "object 5")) << o.problem;
  EXPECT_TRUE(Contains(o.problem, "'box_size' = 0")) << o.problem;
  EXPECT_TRUE(m.object(6).problem.empty());
}

TEST_F(BrokenMeds, ASingularJacobianIsThatCutoutsProblem) {
  set_cell("object_data", "dudrow", 2, 1, 0.0);
  set_cell("object_data", "dudcol", 2, 1, 0.0);
  MedsFile m = MedsFile::open(path);
  const MedsObject o = m.object(2);
  const std::string& p = o.cutouts[1].problem;
  EXPECT_TRUE(Contains(p, "object 2")) << p;
  EXPECT_TRUE(Contains(p, "cutout 1")) << p;
  EXPECT_TRUE(Contains(p, "'dudrow dudcol dvdrow dvdcol'[1]")) << p;
  EXPECT_TRUE(Contains(p, "no inverse")) << p;
}

TEST_F(BrokenMeds, AFileIdOutsideImageInfoAndABadCutoutCountAreNamed) {
  set_cell("object_data", "file_id", 0, 2, 7LL);
  set_cell("object_data", "ncutout", 1, 0, 6LL);
  MedsFile m = MedsFile::open(path);
  EXPECT_TRUE(Contains(m.object(0).cutouts[2].problem, "'file_id'[2] = 7 is not a row of image_info (0..4)"))
      << m.object(0).cutouts[2].problem;
  EXPECT_TRUE(Contains(m.object(1).problem, "'ncutout' = 6 is outside 0..5 (NMAX)")) << m.object(1).problem;
}

TEST_F(BrokenMeds, NotAMedsFileAtAll) {
  const std::string e = error_of<FitsError>(
      [&] { MedsFile::open(std::string(STAMPEDE_DATA_DIR) + "/galsim-great08-mini/nf/set_0.fits"); });
  EXPECT_TRUE(Contains(e, "not a MEDS file: no HDU 'object_data'")) << e;
}

}  // namespace
}  // namespace stampede::io
