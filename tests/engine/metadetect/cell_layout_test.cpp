// Cutting an image into cells (engine/metadetect/cell_layout): where a PSFEx model is evaluated
// for a cell, its centre as the model's 1-based X_IMAGE, Y_IMAGE, and so a varying model's PSF
// differs from cell to cell as the model does.
#include "engine/metadetect/cell_layout.hpp"

#include <gtest/gtest.h>

#include <string>
#include <vector>

#include "engine/model/psfex_model.hpp"

namespace stampede {
namespace {

TEST(CellLayout, APsfexModelIsEvaluatedAtTheCellsCentreInOneBasedPixels) {
  std::string why;
  // A 400 px image in cells of 251 with a 34 px buffer: origins 0 and 149 on each axis.
  const std::vector<CellPlacement> cells = cell_layout(400, 400, 251, 34, &why);
  ASSERT_EQ(cells.size(), 4u) << why;
  const PsfexPosition first = cell_psfex_position(cells[0], 251), last = cell_psfex_position(cells[3], 251);
  // The 0-based centre pixel 125 (of 0..250) is X_IMAGE 126.
  EXPECT_EQ(first.x_image, 126.0);
  EXPECT_EQ(first.y_image, 126.0);
  EXPECT_EQ(last.x_image, 149 + 125 + 1.0);
  EXPECT_EQ(last.y_image, 149 + 125 + 1.0);
  const PsfexPosition right = cell_psfex_position(cells[1], 251);
  EXPECT_EQ(right.x_image, 275.0);
  EXPECT_EQ(right.y_image, 126.0);
  // An even side's centre falls between pixels.
  CellPlacement p;
  p.x0 = 10, p.y0 = 20;
  const PsfexPosition even = cell_psfex_position(p, 64);
  EXPECT_EQ(even.x_image, 10 + 31.5 + 1);
  EXPECT_EQ(even.y_image, 20 + 31.5 + 1);
}

TEST(CellLayout, AVaryingPsfexModelGivesEachCellItsPsf) {
  // Degree 1 on a 3 x 3 basis: the constant term a centred spike, the x term moves light to the
  // right-hand pixel; the model is evaluated where the cells' centres are.
  PsfexModel m;
  m.degree = 1;
  m.nx = m.ny = 3;
  m.zero_x = m.zero_y = 200.5;
  m.scale_x = m.scale_y = 200;
  m.basis.assign(3 * 9, 0.0);
  m.basis[4] = 1;                             // 1
  m.basis[9 + 5] = 0.5, m.basis[9 + 3] = -0.5;  // x: right minus left
  m.basis[18 + 4] = 0;                        // y: nothing
  std::string why;
  ASSERT_TRUE(m.IsValid(&why)) << why;
  const std::vector<CellPlacement> cells = cell_layout(400, 400, 251, 34, &why);
  auto psf_of = [&](const CellPlacement& c) {
    const PsfexPosition at = cell_psfex_position(c, 251);
    std::string error;
    const auto img = m.image_at(at.x_image, at.y_image, &error);
    EXPECT_TRUE(img) << error;
    return img ? img->pixels : std::vector<double>{};
  };
  const std::vector<double> left = psf_of(cells[0]), right = psf_of(cells[1]), below = psf_of(cells[2]);
  // xs = (126 - 200.5) / 200 on the left, (275 - 200.5) / 200 on the right.
  EXPECT_NEAR(left[5], 0.5 * (126 - 200.5) / 200, 1e-15);
  EXPECT_NEAR(right[5], 0.5 * (275 - 200.5) / 200, 1e-15);
  EXPECT_NE(left, right);
  EXPECT_EQ(left, below);  // no y term
}

}  // namespace
}  // namespace stampede
