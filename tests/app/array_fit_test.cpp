// app/array_fit: stamps in memory give the rows a FitRun over the same stamps as a grid file gives,
// bit for bit (every field but time_us), for any thread count; the one-stamp fitter gives the same
// rows; per-stamp PSFs go through the per-object path (a bad one flags its row); inconsistent
// arrays and options are errors naming what is wrong.
#include "app/array_fit.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

#include "app/fit_run.hpp"
#include "io/fits_file.hpp"
#include "support/error_assertions.hpp"
#include "support/scratch_dir.hpp"

namespace {

using namespace stampede;
using stampede::testing::Contains;
using stampede::testing::error_of;

constexpr int kNx = 4, kNy = 2, kStamp = 39, kCount = kNx * kNy;

// The first kNx x kNy stamps of the GREAT08-mini S/N 40 set, as (grid image, stamps in id order).
struct SmallSet {
  std::vector<double> grid;    // (kNy * kStamp) x (kNx * kStamp)
  std::vector<double> stamps;  // kCount x kStamp^2
};
SmallSet small_set() {
  io::FitsFile in = io::FitsFile::open_read(std::string(STAMPEDE_DATA_DIR) + "/galsim-great08-mini/snr40/set_0.fits");
  const long width = in.image_shape().nx;
  const std::vector<double> all = in.read_image();
  SmallSet s;
  for (long y = 0; y < kNy * kStamp; ++y)
    s.grid.insert(s.grid.end(), all.begin() + y * width, all.begin() + y * width + kNx * kStamp);
  for (int k = 0; k < kCount; ++k)
    for (int y = 0; y < kStamp; ++y) {
      const auto row = s.grid.begin() + ((k / kNx) * kStamp + y) * kNx * kStamp + (k % kNx) * kStamp;
      s.stamps.insert(s.stamps.end(), row, row + kStamp);
    }
  return s;
}

app::RunConfig cheap_config() {
  app::RunConfig cfg;
  for (const char* s : {"psf_beta=3", "psf_fwhm=2.85", "psf_e2=0.05", "noise_sigma=1", "renderer=exact",
                        "minimizer_max_iterations=30", "batch_size=3"})
    app::apply_set(cfg, s);
  return cfg;
}

bool same_bits(double a, double b) { return std::memcmp(&a, &b, sizeof a) == 0; }

// Every field the table holds, except the wall time.
void expect_same_row(const ObjectRecord& a, const ObjectRecord& b, int k) {
  EXPECT_EQ(a.id, b.id) << k;
  EXPECT_EQ(a.ix, b.ix) << k;
  EXPECT_EQ(a.iy, b.iy) << k;
  EXPECT_EQ(a.flags, b.flags) << k;
  EXPECT_EQ(a.fit.status, b.fit.status) << k;
  EXPECT_EQ(a.fit.iterations, b.fit.iterations) << k;
  EXPECT_EQ(a.fit.evaluations, b.fit.evaluations) << k;
  for (std::size_t p = 0; p < a.fit.params.size(); ++p) EXPECT_TRUE(same_bits(a.fit.params[p], b.fit.params[p])) << k;
  for (const auto& [x, y] : {std::pair{a.fit.chi2, b.fit.chi2}, std::pair{a.fit.e1_err, b.fit.e1_err},
                             std::pair{a.fit.flux, b.fit.flux}, std::pair{a.fit.snr, b.fit.snr},
                             std::pair{a.psf_e2, b.psf_e2}})
    EXPECT_TRUE(same_bits(x, y)) << k;
}

TEST(ArrayFit, RowsEqualAFitRunOverTheSameGridForAnyThreadCount) {
  const SmallSet s = small_set();
  const stampede::testing::ScratchDir scratch("stampede_array_fit_");
  const std::string grid = scratch.path("grid.fits");
  {
    io::FitsFile out = io::FitsFile::create(grid, true);
    out.write_image(kNx * kStamp, kNy * kStamp, s.grid);
    out.write_key("STAMPSZ", kStamp, "stamp size");
  }
  app::FitRunOptions o;
  o.input = grid;
  o.threads = 2;
  o.config = cheap_config();
  std::vector<ObjectRecord> run_rows;
  o.on_rows = [&](std::span<const ObjectRecord> b) { run_rows.insert(run_rows.end(), b.begin(), b.end()); };
  app::FitRun(o).run();
  ASSERT_EQ(run_rows.size(), static_cast<std::size_t>(kCount));

  app::ArrayStamps in;
  in.count = kCount;
  in.stamp_size = kStamp;
  in.pixels = s.stamps;
  in.grid_nx = kNx;
  for (int threads : {1, 2}) {
    const std::vector<ObjectRecord> rows = app::fit_array_stamps(cheap_config(), in, threads);
    ASSERT_EQ(rows.size(), static_cast<std::size_t>(kCount));
    for (int k = 0; k < kCount; ++k) expect_same_row(rows[k], run_rows[k], k);
  }
  EXPECT_EQ(run_rows[5].ix, 1);
  EXPECT_EQ(run_rows[5].iy, 1);
}

TEST(ArrayFit, TheOneStampFitterGivesTheBatchRows) {
  const SmallSet s = small_set();
  app::ArrayStamps in;
  in.count = kCount;
  in.stamp_size = kStamp;
  in.pixels = s.stamps;
  in.first_id = 1000;
  const std::vector<ObjectRecord> rows = app::fit_array_stamps(cheap_config(), in, 2);
  app::SingleStampFitter one(cheap_config(), kStamp, std::nullopt);
  for (int k = 0; k < kCount; ++k) {
    ObjectRecord r = one.fit({s.stamps.data() + k * kStamp * kStamp, kStamp * kStamp}, {}, 1000 + k);
    r.ix = k;  // the batch numbers one grid row of kCount stamps
    expect_same_row(r, rows[k], k);
  }
  EXPECT_EQ(rows[3].id, 1003);
  EXPECT_TRUE(Contains(error_of<std::invalid_argument>([&] { one.fit({s.stamps.data(), 100}, {}, 0); }),
                       "a stamp of 39 x 39 pixels was expected, not 100 values"));
}

TEST(ArrayFit, APsfPerStampGoesThroughThePerObjectPathAndABadOneFlagsItsRow) {
  const SmallSet s = small_set();
  kernels::MoffatProfile m;
  m.beta = 3;
  m.fwhm = 2.85;
  m.e2 = 0.05;
  app::ArrayStamps in;
  in.count = 3;
  in.stamp_size = kStamp;
  in.pixels = {s.stamps.data(), 3 * kStamp * kStamp};
  in.psfs = {PsfModel::Moffat(m)};
  app::RunConfig cfg = cheap_config();
  const std::vector<ObjectRecord> shared = app::fit_array_stamps(cfg, in, 1);
  const auto empty = std::make_shared<PsfImage>();
  empty->nx = empty->ny = 5;
  empty->pixels.assign(25, 0.0);  // cannot be normalised
  in.psfs = {PsfModel::Moffat(m), PsfModel::Image(empty), PsfModel::Moffat(m)};
  app::apply_set(cfg, "renderer=upsampled");  // the exact renderer takes analytic PSFs only
  app::apply_set(cfg, "upsampling=2");
  app::apply_set(cfg, "n_central_pixels_to_upsample=1");
  const std::vector<ObjectRecord> per = app::fit_array_stamps(cfg, in, 2);
  EXPECT_FALSE(per[0].flags & kFlagPsfFailure);
  EXPECT_TRUE(per[1].flags & kFlagPsfFailure);
  EXPECT_FALSE(per[2].flags & kFlagPsfFailure);
  EXPECT_EQ(shared[0].fit.status, FitStatus::kOk);
}

TEST(ArrayFit, InconsistentArraysAndOptionsAreErrors) {
  std::vector<double> pixels(2 * 9 * 9, 1.0);
  app::ArrayStamps in;
  in.count = 2;
  in.stamp_size = 9;
  in.pixels = {pixels.data(), 100};
  const app::RunConfig cfg = cheap_config();
  EXPECT_TRUE(Contains(error_of<std::invalid_argument>([&] { app::fit_array_stamps(cfg, in, 1); }),
                       "stamps hold 100 values, not 2 x 9^2"));
  in.pixels = pixels;
  in.weights = {pixels.data(), 81};
  EXPECT_TRUE(Contains(error_of<std::invalid_argument>([&] { app::fit_array_stamps(cfg, in, 1); }),
                       "weights hold 81 values, the stamps 162"));
  in.weights = {};
  in.psfs.resize(3);
  EXPECT_TRUE(Contains(error_of<std::invalid_argument>([&] { app::fit_array_stamps(cfg, in, 1); }),
                       "3 PSFs for 2 stamps"));
  in.psfs.clear();
  app::RunConfig sized = cfg;
  app::apply_set(sized, "stamp_size=39");
  EXPECT_TRUE(Contains(error_of<io::ConfigError>([&] { app::fit_array_stamps(sized, in, 1); }),
                       "option 'stamp_size' = 39 but the stamps are 9 pixels square"));
  app::RunConfig catalogue_psf = cfg;
  app::apply_set(catalogue_psf, "psf_input=moffat_catalog");
  EXPECT_TRUE(Contains(error_of<io::ConfigError>([&] { app::fit_array_stamps(catalogue_psf, in, 1); }),
                       "needs a PSF per stamp"));
}

}  // namespace
