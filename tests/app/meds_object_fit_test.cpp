// Tests for one MEDS object's joint fit (app/meds_object_fit) on the tile the meds package wrote
// (../shared/data/meds-sample: 24 bulge + disc galaxies, four epochs each with random WCS, PSFEx
// PSFs, S/N ~30 per epoch): every object fitted on its four epochs gives its true sky ellipticity
// within its errors; the PSF each cutout used is its PSFEx model at the object's position; uberseg
// against a hand-built seg map; a missing PSFEx file is a flagged row naming the file.
#include "app/meds_object_fit.hpp"

#include <gtest/gtest.h>

#include <fitsio.h>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <vector>

#include "io/fits_file.hpp"
#include "io/meds_writer.hpp"
#include "support/scratch_dir.hpp"

namespace stampede::app {
namespace {

const std::string kSample = std::string(STAMPEDE_DATA_DIR) + "/meds-sample";

MedsFitOptions options() {
  MedsFitOptions o;
  o.fitter.renderer = RendererKind::kExact;
  return o;
}

TEST(MedsObjectFit, TheSampleTilesObjectsGiveTheirTrueShapes) {
  io::MedsFile meds = io::MedsFile::open(kSample + "/meds.fits");
  MedsObjectFitter fitter(meds, options());
  io::FitsFile truth = io::FitsFile::open_read(kSample + "/truth.fits");
  truth.move_to("OBJECTS");
  const std::vector<double> e1 = truth.read_column("e1_obs"), e2 = truth.read_column("e2_obs"), id = truth.read_column("id");
  double chi2 = 0, worst = 0;
  int n = 0;
  for (long long row = 0; row < meds.size(); ++row) {
    const MedsObjectResult r = fitter.fit(row);
    ASSERT_EQ(r.fit.status, FitStatus::kOk) << "object " << row << ": " << r.problem;
    EXPECT_EQ(r.n_epochs, 4);
    EXPECT_EQ(r.id, static_cast<std::int64_t>(id[row]));
    const double p1 = (r.fit.params[index(Param::kE1)] - e1[row]) / r.fit.e1_err;
    const double p2 = (r.fit.params[index(Param::kE2)] - e2[row]) / r.fit.e2_err;
    chi2 += p1 * p1 + p2 * p2, n += 2;
    worst = std::max({worst, std::abs(p1), std::abs(p2)});
  }
  std::printf("24 objects, 4 epochs each: (e - e_true) / error: rms %.2f, worst %.2f\n", std::sqrt(chi2 / n), worst);
  EXPECT_LT(std::sqrt(chi2 / n), 1.5);  // errors that are right give ~1 (48 values: 1.5 is 4 sigma above)
  EXPECT_LT(worst, 4.5);
}

// Must-show 4: the PSF a cutout's fit used is its source image's PSFEx model at the object's
// position there: the tile writer's own stamps (truth PSF_STAMPS, rows in cutout order).
TEST(MedsObjectFit, EachCutoutUsesItsPsfexModelAtTheObjectsPosition) {
  io::MedsFile meds = io::MedsFile::open(kSample + "/meds.fits");
  MedsObjectFitter fitter(meds, options());
  fitsfile* f = nullptr;
  int status = 0;
  fits_open_file(&f, (kSample + "/truth.fits[PSF_STAMPS]").c_str(), READONLY, &status);
  std::vector<double> stamps(41 * 41 * 120);
  int anynul = 0;
  fits_read_img(f, TDOUBLE, 1, static_cast<LONGLONG>(stamps.size()), nullptr, stamps.data(), &anynul, &status);
  fits_close_file(f, &status);
  ASSERT_EQ(status, 0);
  double worst = 0;
  for (long long row : {0LL, 7LL, 23LL}) {
    fitter.fit(row);
    ASSERT_EQ(fitter.last_psfs().size(), 4u);
    for (int k = 1; k <= 4; ++k) {  // cutouts 1..4 of the object: truth row 5 row + k
      const PsfImage& used = *fitter.last_psfs()[static_cast<std::size_t>(k - 1)];
      const double* want = stamps.data() + (5 * row + k) * 41 * 41;
      double sum = 0, peak = 0;
      for (int p = 0; p < 41 * 41; ++p) sum += want[p], peak = std::max(peak, want[p]);
      for (int p = 0; p < 41 * 41; ++p) worst = std::max(worst, std::abs(used.pixels[p] - want[p] / sum) * sum / peak);
      EXPECT_EQ(used.centre_x, 20.0);
    }
  }
  EXPECT_LT(worst, 2e-6);
}

// bord: a pure bulge and a pure disc, the better likelihood kept; each is the single-component
// fit alone, and its other amplitude is 0.
TEST(MedsObjectFit, BulgeOrDiscKeepsTheBetterLikelihood) {
  io::MedsFile meds = io::MedsFile::open(kSample + "/meds.fits");
  MedsFitOptions o = options();
  o.model = MedsModel::kBulgeOrDisc;
  MedsObjectFitter bord(meds, o);
  int bulges = 0;
  for (long long row = 0; row < 6; ++row) {
    const MedsObjectResult r = bord.fit(row);
    ASSERT_EQ(r.fit.status, FitStatus::kOk) << r.problem;
    EXPECT_GE(r.fit.likelihood, r.other_likelihood);
    EXPECT_EQ(r.fit.params[index(r.is_bulge ? Param::kDiscA : Param::kBulgeA)], 0.0);
    EXPECT_GT(r.fit.params[index(r.is_bulge ? Param::kBulgeA : Param::kDiscA)], 0.0);
    bulges += r.is_bulge;
  }
  std::printf("bord: %d of 6 objects fitted best by the pure bulge\n", bulges);
}

// Uberseg on a hand-built 6 x 6 seg map: object 5 in the top-left, object 9 in the bottom-right;
// each pixel keeps its weight unless a pixel of 9 is strictly nearer than every pixel of 5.
TEST(MedsObjectFit, UbersegMasksWhatIsNearerAnotherObject) {
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

TEST(MedsObjectFit, AMissingPsfexFileIsAFlaggedRowNamingIt) {
  stampede::testing::ScratchDir dir("stampede_meds_fit_");
  io::MedsFile meds = io::MedsFile::open(kSample + "/meds.fits");
  MedsFitOptions o = options();
  o.psf_dir = dir.path("nowhere");
  MedsObjectFitter fitter(meds, o);
  const MedsObjectResult r = fitter.fit(0);
  EXPECT_EQ(r.n_epochs, 0);
  EXPECT_TRUE(r.flags & kFlagNoUsableEpoch);
  EXPECT_TRUE(r.flags & kFlagPsfFailure);
  EXPECT_NE(r.problem.find("nowhere/psfex/se_e1.psf"), std::string::npos) << r.problem;
  EXPECT_NE(r.problem.find("cutout 1"), std::string::npos) << r.problem;
}

}  // namespace
}  // namespace stampede::app

namespace stampede::app {
namespace {

// A box size the arrays really hold but no galaxy fit needs (a corrupt row, or a star mask's
// cutout) is a flagged row: fitting it would cost gigabytes of Fourier grids.
TEST(MedsObjectFit, AnOversizedBoxIsAFlaggedRowNotAnAllocation) {
  testing::ScratchDir dir("stampede_meds_fit_");
  io::MedsObjectLayout big;
  big.id = big.number = 1, big.box_size = 1100;
  big.cutouts.resize(2);
  for (io::MedsCutout& c : big.cutouts) c.dudcol = c.dvdrow = 0.263, c.cutout_row = c.cutout_col = 549.5;
  big.cutouts[1].file_id = 1;
  std::vector<io::MedsImageInfo> images(2);
  {
    io::MedsWriter w(dir.path("big.fits"), {big}, images, {io::MedsCutoutType::kWeight});
    const std::vector<double> ones(1100 * 1100, 1.0);
    for (int k = 0; k < 2; ++k)
      for (io::MedsCutoutType t : {io::MedsCutoutType::kImage, io::MedsCutoutType::kWeight}) w.write_cutout(0, k, t, ones);
    w.finish();
  }
  io::MedsFile meds = io::MedsFile::open(dir.path("big.fits"));
  ASSERT_TRUE(meds.object(0).cutouts[1].problem.empty());
  MedsObjectFitter fitter(meds, options());
  const MedsObjectResult r = fitter.fit(0);
  EXPECT_TRUE(r.flags & kFlagNoUsableEpoch);
  EXPECT_NE(r.problem.find("'box_size' = 1100 is larger than a galaxy fit takes (1024)"), std::string::npos) << r.problem;
}

}  // namespace
}  // namespace stampede::app
