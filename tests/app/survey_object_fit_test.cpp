// Tests for one survey object's joint fit (app/survey_object_fit) on the observations the MEDS
// source reads (io/meds_object_source), on the tile the meds package wrote
// (../shared/data/meds-sample: 24 bulge + disc galaxies, four epochs each with random WCS, PSFEx
// PSFs, S/N ~30 per epoch): every object fitted on its four epochs gives its true sky ellipticity
// within its errors; the PSF each cutout used is its PSFEx model at the object's position; a
// missing PSFEx file is a flagged row naming the file.
#include "app/survey_object_fit.hpp"

#include <gtest/gtest.h>

#include <fitsio.h>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <vector>

#include "io/fits_file.hpp"
#include "io/meds_object_source.hpp"
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

// One object at a time as a run does it: the source reads the row into a batch's arena (the serial
// stage), the fitter fits it from there (a fit stage).
class OneObject {
 public:
  OneObject(const std::string& tile, const MedsFitOptions& o)
      : source_({tile}, o, o.psf_model), fitter_(o, {tile}, {}), batch_(1) {}
  long long size() const { return source_.total_objects(); }
  MedsObjectResult fit(long long row) {
    source_.skip_to(row);
    EXPECT_TRUE(source_.fill(batch_));
    return fitter_.fit(batch_.observations, 0, row, batch_.records[0]);
  }
  const ObservationArena& arena() const { return batch_.observations; }

 private:
  io::MedsObjectSource source_;
  SurveyObjectFitter fitter_;
  StampBatch batch_;
};

TEST(SurveyObjectFit, TheSampleTilesObjectsGiveTheirTrueShapes) {
  OneObject fitter(kSample + "/meds.fits", options());
  io::FitsFile truth = io::FitsFile::open_read(kSample + "/truth.fits");
  truth.move_to("OBJECTS");
  const std::vector<double> e1 = truth.read_column("e1_obs"), e2 = truth.read_column("e2_obs"), id = truth.read_column("id");
  double chi2 = 0, worst = 0;
  int n = 0;
  for (long long row = 0; row < fitter.size(); ++row) {
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
TEST(SurveyObjectFit, EachCutoutUsesItsPsfexModelAtTheObjectsPosition) {
  OneObject fitter(kSample + "/meds.fits", options());
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
    ASSERT_EQ(fitter.arena().size(), 4);
    for (int k = 1; k <= 4; ++k) {  // cutouts 1..4 of the object: truth row 5 row + k
      const ArenaObservation& observation = fitter.arena()[k - 1];
      EXPECT_EQ(observation.cutout, k);
      ASSERT_TRUE(observation.psf_from_image);
      const PsfImage& used = *observation.psf.image;
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
TEST(SurveyObjectFit, BulgeOrDiscKeepsTheBetterLikelihood) {
  MedsFitOptions o = options();
  o.model = MedsModel::kBulgeOrDisc;
  OneObject bord(kSample + "/meds.fits", o);
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

TEST(SurveyObjectFit, AMissingPsfexFileIsAFlaggedRowNamingIt) {
  stampede::testing::ScratchDir dir("stampede_meds_fit_");
  MedsFitOptions o = options();
  o.psf_dir = dir.path("nowhere");
  OneObject fitter(kSample + "/meds.fits", o);
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
TEST(SurveyObjectFit, AnOversizedBoxIsAFlaggedRowNotAnAllocation) {
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
  OneObject fitter(dir.path("big.fits"), options());
  const MedsObjectResult r = fitter.fit(0);
  EXPECT_TRUE(r.flags & kFlagNoUsableEpoch);
  EXPECT_NE(r.problem.find("'box_size' = 1100 is larger than a galaxy fit takes (1024)"), std::string::npos) << r.problem;
}

}  // namespace
}  // namespace stampede::app
