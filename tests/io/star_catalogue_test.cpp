// The bright-star mask catalogue (io/star_catalogue): rows become discs in 0-based pixels with the
// margin added; a missing column, a bad row or a file without a table is a FitsError naming the
// file, the HDU, the column or the row.
#include "io/star_catalogue.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <string>
#include <vector>

#include "io/fits_error.hpp"
#include "io/fits_file.hpp"
#include "support/scratch_dir.hpp"

namespace stampede::io {
namespace {

std::string write_stars(const testing::ScratchDir& dir, const std::string& name,
                        const std::vector<FitsFile::OutputColumn>& columns) {
  const std::string path = dir.path(name);
  FitsFile f = FitsFile::create(path, true);
  f.write_empty_image();
  f.write_table("STARS", columns);
  f.close();
  return path;
}

std::string error_of(const std::string& path) {
  try {
    read_star_catalogue(path, 0);
  } catch (const FitsError& e) {
    return e.what();
  }
  return "no error";
}

TEST(StarCatalogue, RowsAreDiscsInZeroBasedPixelsWithTheMargin) {
  testing::ScratchDir dir("stampede_stars_");
  const std::string path =
      write_stars(dir, "stars.fits", {{"x", false, {10.5, 200}}, {"y", false, {1, 33.25}}, {"radius", false, {4, 12.5}}});
  const std::vector<StarDisc> s = read_star_catalogue(path, 1.5);
  ASSERT_EQ(s.size(), 2u);
  EXPECT_EQ(s[0].x, 9.5);
  EXPECT_EQ(s[0].y, 0.0);
  EXPECT_EQ(s[0].radius, 5.5);
  EXPECT_EQ(s[1].x, 199.0);
  EXPECT_EQ(s[1].y, 32.25);
  EXPECT_EQ(s[1].radius, 14.0);
  EXPECT_TRUE(s[0].holds(9.5, 5.4));
  EXPECT_FALSE(s[0].holds(9.5, 5.6));
}

TEST(StarCatalogue, BadCataloguesAreNamedByFileHduColumnAndRow) {
  testing::ScratchDir dir("stampede_stars_bad_");
  const std::string no_radius = write_stars(dir, "a.fits", {{"x", false, {1}}, {"y", false, {2}}});
  const std::string e1 = error_of(no_radius);
  EXPECT_NE(e1.find(no_radius + "[HDU 1 'STARS']: no column 'radius'"), std::string::npos) << e1;
  const std::string bad_row =
      write_stars(dir, "b.fits", {{"x", false, {1, 2, NAN}}, {"y", false, {2, 3, 4}}, {"radius", false, {1, 2, 3}}});
  EXPECT_NE(error_of(bad_row).find("row 3 has x = nan"), std::string::npos) << error_of(bad_row);
  const std::string zero =
      write_stars(dir, "c.fits", {{"x", false, {1}}, {"y", false, {2}}, {"radius", false, {0}}});
  EXPECT_NE(error_of(zero).find("row 1 has x = 1, y = 2, radius = 0: positions must be finite and the radius positive"),
            std::string::npos) << error_of(zero);
  const std::string image = dir.path("image.fits");
  {
    FitsFile f = FitsFile::create(image, true);
    f.write_image(3, 3, std::vector<double>(9, 0.0));
    f.close();
  }
  EXPECT_NE(error_of(image).find(image + ": no binary table"), std::string::npos) << error_of(image);
}

}  // namespace
}  // namespace stampede::io
