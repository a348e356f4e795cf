// End-to-end tests of `stampede fit IMAGE --catalog CAT` over an image of GalSim GREAT08-mini
// stamps: interior objects fit as the grid does, objects at or over the edge are masked, flagged
// and kept, text and FITS catalogues agree, and psf_input = moffat_catalog takes each row's PSF.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <fstream>
#include <string>
#include <vector>

#include "io/fits_file.hpp"
#include "support/fit_output.hpp"

namespace {

using stampede::io::FitsFile;
using stampede::testing::column;
using stampede::testing::expect_tables_equal;
using stampede::testing::kGreat08Psf;
using stampede::testing::RunResult;
using stampede::testing::operator+;
using FitCatalogue = stampede::testing::FitCommandTest;

constexpr int kStamp = 39, kNx = 4, kNy = 3;  // the test image: the first 4 x 3 stamps of set_0
constexpr std::uint32_t kMasked = 1u << 0, kEdge = 1u << 16, kPsfFailure = 1u << 17;

// The fitted columns of a catalogue run (positions differ in kind from the grid's id ix iy).
const std::vector<std::string> kFitted = {"x0", "y0", "e1", "e2", "radius", "bulge_A", "disc_A", "flux", "e1_err",
                                          "e2_err", "chi2", "n_iter", "n_eval", "status"};

struct Object {
  long long id;
  double x, y;  // FITS 1-based
  double beta = 3.0, fwhm = 2.85, e1 = 0.0, e2 = 0.05;
};

// Stamp (ix, iy) of the grid is centred on 1-based pixel (ix * 39 + 20, iy * 39 + 20), so a
// catalogue object there is cut from exactly the grid stamp's pixels.
Object at_stamp(int ix, int iy) { return {1000 + iy * kNx + ix, ix * kStamp + 20.0, iy * kStamp + 20.0}; }

class FitCatalogueTest : public FitCatalogue {
 protected:
  void SetUp() override { stampede::testing::write_great08_stamps(path("image.fits"), kNx, kNy); }
  static void write_text(const std::string& file, const std::vector<Object>& objects, bool with_psf) {
    std::ofstream f(file);
    f.precision(17);
    f << "# id x y" << (with_psf ? " psf_beta psf_fwhm psf_e1 psf_e2" : "") << "\n";
    for (const Object& o : objects) {
      f << o.id << " " << o.x << " " << o.y;
      if (with_psf) f << " " << o.beta << " " << o.fwhm << " " << o.e1 << " " << o.e2;
      f << "\n";
    }
  }
  RunResult fit(const std::string& catalogue, const std::string& out, std::vector<std::string> extra = {}) {
    return run(std::vector<std::string>{path("image.fits"), "-o", out, "--catalog", catalogue, "--quiet", "--threads",
                                        "2", "--set", "noise_sigma=1"} +
               extra);
  }
};

// noise_sigma = 1 for both: the catalogue source always weights its pixels (the edge mask lives in
// the weights), so the grid run is weighted too and both fit the same chi2.
TEST_F(FitCatalogueTest, InteriorObjectsFitAsTheGridAndEdgeObjectsAreMaskedFlaggedAndKept) {
  ASSERT_EQ(run(std::vector<std::string>{path("image.fits"), "-o", path("grid.fits"), "--quiet", "--set", "noise_sigma=1"} +
                kGreat08Psf)
                .exit_code,
            0);
  const std::vector<Object> interior = {at_stamp(0, 0), at_stamp(2, 1), at_stamp(3, 2), at_stamp(1, 2)};
  std::vector<Object> objects = interior;
  objects.push_back({7, 12.0, 60.0});     // 8 columns of its stamp left of the image
  objects.push_back({8, 150.0, 114.5});   // over the top-right corner
  objects.push_back({9, 165.0, 60.0});    // centre beyond the right edge, 11 columns inside
  objects.push_back({10, -80.0, -80.0});  // entirely outside: nothing to fit, still a row
  write_text(path("cat.txt"), objects, false);
  const RunResult r = fit(path("cat.txt"), path("cat.fits"), kGreat08Psf);
  ASSERT_EQ(r.exit_code, 0) << r.err;

  const auto id = column(path("cat.fits"), "id"), x = column(path("cat.fits"), "x_image"),
             y = column(path("cat.fits"), "y_image"), flags = column(path("cat.fits"), "flags"),
             status = column(path("cat.fits"), "status");
  ASSERT_EQ(id.size(), objects.size());
  for (std::size_t i = 0; i < objects.size(); ++i) {
    EXPECT_EQ(id[i], objects[i].id) << i;
    EXPECT_EQ(x[i], objects[i].x) << i;
    EXPECT_EQ(y[i], objects[i].y) << i;
  }
  // Interior: the grid stamp's pixels, so the same fit, bitwise.
  for (std::size_t i = 0; i < interior.size(); ++i) {
    const auto flag_bits = static_cast<std::uint32_t>(flags[i]);
    EXPECT_EQ(flag_bits & (kEdge | kMasked), 0u) << i;
    const long long grid_row = interior[i].id - 1000;  // iy * kNx + ix
    for (const std::string& name : kFitted) {
      const double a = column(path("cat.fits"), name)[i], b = column(path("grid.fits"), name)[grid_row];
      EXPECT_EQ(a, b) << name << " of object " << interior[i].id;
    }
  }
  // Edge: outside pixels masked (weight 0), flagged, and the visible part still fitted.
  for (std::size_t i = interior.size(); i < objects.size(); ++i) {
    const auto flag_bits = static_cast<std::uint32_t>(flags[i]);
    EXPECT_TRUE(flag_bits & kEdge) << objects[i].id;
  }
  const std::size_t left = interior.size(), corner = left + 1;
  for (std::size_t i : {left, corner}) EXPECT_TRUE(static_cast<std::uint32_t>(flags[i]) & kMasked) << objects[i].id;
  EXPECT_TRUE(status[left] == 0 || status[left] == 1) << "partly inside, with its galaxy: fitted";
  EXPECT_EQ(status.back(), 3) << "an object wholly outside has no data";  // FitStatus::kNoData
  // The object 8 px left of stamp (0, 1)'s centre finds that galaxy 8 px right, in stamp coordinates.
  const auto x0 = column(path("cat.fits"), "x0"), grid_x0 = column(path("grid.fits"), "x0");
  EXPECT_NEAR(x0[left], grid_x0[kNx] + 8.0, 0.05);
}

TEST_F(FitCatalogueTest, FitsTableCatalogueGivesTheSameTableAsTheTextOne) {
  const std::vector<Object> objects = {at_stamp(1, 1), at_stamp(3, 0), {5, 10.0, 30.0}};
  write_text(path("cat.txt"), objects, false);
  {
    std::vector<FitsFile::OutputColumn> cols = {{"id", true, {}}, {"x", false, {}}, {"y", false, {}}};
    for (const Object& o : objects) {
      cols[0].values.push_back(static_cast<double>(o.id));
      cols[1].values.push_back(o.x);
      cols[2].values.push_back(o.y);
    }
    auto f = FitsFile::create(path("cat_table.fits"), true);
    f.write_empty_image();
    f.write_table("OBJECTS", cols);
  }
  ASSERT_EQ(fit(path("cat.txt"), path("a.fits"), kGreat08Psf).exit_code, 0);
  const RunResult r = fit(path("cat_table.fits"), path("b.fits"), kGreat08Psf);
  ASSERT_EQ(r.exit_code, 0) << r.err;
  expect_tables_equal(path("a.fits"), path("b.fits"), std::vector<std::string>{"id", "x_image", "y_image", "flags",
                                                                               "psf_e1", "psf_e2", "psf_fwhm"} + kFitted);
  EXPECT_EQ(column(path("b.fits"), "id").size(), objects.size());
}

// psf_input = moffat_catalog: every row carries its own PSF. A row with the run's fiducial PSF
// fits exactly as the shared-PSF run; a row whose PSF cannot be built is a flagged row.
TEST_F(FitCatalogueTest, MoffatCatalogueTakesEachRowsPsf) {
  std::vector<Object> objects = {at_stamp(0, 0), at_stamp(2, 1), at_stamp(1, 2), at_stamp(3, 1), at_stamp(2, 2)};
  objects[1].beta = 2.5, objects[1].fwhm = 2.6, objects[1].e1 = -0.02, objects[1].e2 = 0.03;
  objects[2].beta = 3.5, objects[2].fwhm = 3.1, objects[2].e1 = 0.01, objects[2].e2 = -0.04;
  objects[3].fwhm = 0.0;  // no PSF has zero width
  objects[4].beta = 0.8;  // a Moffat needs beta > 1 for a finite flux
  write_text(path("psf.txt"), objects, true);
  const RunResult r = fit(path("psf.txt"), path("psf.fits"), {"--set", "psf_input=moffat_catalog"});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  write_text(path("cat.txt"), objects, false);
  ASSERT_EQ(fit(path("cat.txt"), path("shared.fits"), kGreat08Psf).exit_code, 0);

  const auto id = column(path("psf.fits"), "id"), flags = column(path("psf.fits"), "flags"),
             pe1 = column(path("psf.fits"), "psf_e1"), pe2 = column(path("psf.fits"), "psf_e2"),
             pfwhm = column(path("psf.fits"), "psf_fwhm"), status = column(path("psf.fits"), "status");
  ASSERT_EQ(id.size(), objects.size());
  for (std::size_t i = 0; i < 3; ++i) {
    EXPECT_EQ(id[i], objects[i].id);
    EXPECT_EQ(pe1[i], objects[i].e1) << i;
    EXPECT_EQ(pe2[i], objects[i].e2) << i;
    EXPECT_EQ(pfwhm[i], objects[i].fwhm) << i;
    EXPECT_EQ(static_cast<std::uint32_t>(flags[i]) & kPsfFailure, 0u) << i;
  }
  for (const std::string& name : kFitted) EXPECT_EQ(column(path("psf.fits"), name)[0], column(path("shared.fits"), name)[0]) << name;
  // Another PSF, another fit: the row's PSF was used, not the fiducial one.
  EXPECT_NE(column(path("psf.fits"), "e1")[1], column(path("shared.fits"), "e1")[1]);
  EXPECT_NE(column(path("psf.fits"), "e1")[2], column(path("shared.fits"), "e1")[2]);
  for (std::size_t i = 3; i < 5; ++i) {
    EXPECT_EQ(id[i], objects[i].id);
    EXPECT_TRUE(static_cast<std::uint32_t>(flags[i]) & kPsfFailure) << objects[i].id;
    EXPECT_NE(status[i], 0) << objects[i].id;
  }
}

}  // namespace
