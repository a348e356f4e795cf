// End-to-end tests of two `stampede fit` run options over GalSim GREAT08-mini stamps: save_images
// (DATA, MODEL and RESID images of the named objects) and fft_wisdom (FFTW plans measured once,
// saved, loaded by later runs, with the same table for any thread count).
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <numeric>
#include <string>
#include <vector>

#include "io/fits_error.hpp"
#include "io/fits_file.hpp"
#include "support/fit_output.hpp"

namespace {

using stampede::io::FitsFile;
using stampede::testing::column;
using stampede::testing::expect_tables_equal;
using stampede::testing::kGreat08Psf;
using stampede::testing::RunResult;
using stampede::testing::operator+;
using FitRunOptions = stampede::testing::FitCommandTest;

constexpr int kStamp = 39, kNx = 3, kNy = 2;

std::vector<double> image_hdu(const std::string& file, const std::string& name) {
  auto f = FitsFile::open_read(file);
  f.move_to(name);
  return f.read_image();
}

TEST_F(FitRunOptions, SaveImagesWritesDataModelAndResidualOfTheNamedObjects) {
  stampede::testing::write_great08_stamps(path("image.fits"), kNx, kNy);
  const RunResult r = run(std::vector<std::string>{path("image.fits"), "-o", path("out.fits"), "--quiet", "--set",
                                                   "noise_sigma=1", "--set", "save_images=1,5"} +
                          kGreat08Psf);
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const std::string images = path("out.images.fits");
  ASSERT_TRUE(std::filesystem::exists(images));
  auto input = FitsFile::open_read(path("image.fits"));
  const auto flux = column(path("out.fits"), "flux");
  for (int id : {1, 5}) {
    const std::string n = std::to_string(id);
    const auto data = image_hdu(images, "DATA_" + n), model = image_hdu(images, "MODEL_" + n),
               resid = image_hdu(images, "RESID_" + n);
    ASSERT_EQ(data.size(), static_cast<std::size_t>(kStamp * kStamp));
    ASSERT_EQ(model.size(), data.size());
    ASSERT_EQ(resid.size(), data.size());
    std::vector<double> stamp(data.size());
    input.read_image_region((id % kNx) * kStamp, (id / kNx) * kStamp, kStamp, kStamp, stamp);
    EXPECT_EQ(data, stamp) << "DATA_" << n << " is the input stamp";
    for (std::size_t i = 0; i < data.size(); ++i) ASSERT_EQ(resid[i], data[i] - model[i]) << n << " pixel " << i;
    // The model's light inside the stamp: the row's flux less the de Vaucouleurs wings beyond a
    // 39 px stamp (up to ~5% here), and, the fit being good, close to the data's sum.
    const double sum = std::accumulate(model.begin(), model.end(), 0.0);
    const double data_sum = std::accumulate(data.begin(), data.end(), 0.0);
    EXPECT_LE(sum, flux[id]) << n;
    EXPECT_GT(sum, 0.9 * flux[id]) << n;
    EXPECT_NEAR(sum / data_sum, 1.0, 1e-2) << n;
  }
  // Only the named objects are saved.
  auto f = FitsFile::open_read(images);
  EXPECT_THROW(f.move_to("DATA_0"), stampede::io::FitsError);
}

// The first run measures plans and writes the wisdom file; later runs load it. Measured plans are
// fixed by the wisdom, so every run (1 or 2 threads) gives the same table, bitwise.
TEST_F(FitRunOptions, FftWisdomIsWrittenThenLoadedWithTheSameTables) {
  stampede::testing::write_great08_stamps(path("image.fits"), kNx, kNy);
  const std::string wisdom = path("fftw.wisdom");
  auto fit = [&](const std::string& out, const char* threads) {
    return run(std::vector<std::string>{path("image.fits"), "-o", path(out), "--quiet", "--threads", threads, "--set",
                                        "fft_wisdom=" + wisdom} +
               kGreat08Psf);
  };
  RunResult r = fit("first.fits", "1");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  ASSERT_TRUE(std::filesystem::exists(wisdom)) << "the first run writes the wisdom";
  EXPECT_GT(std::filesystem::file_size(wisdom), 0u);
  const auto written = std::filesystem::last_write_time(wisdom);
  r = fit("second.fits", "2");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  r = fit("third.fits", "1");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_GE(std::filesystem::last_write_time(wisdom), written);
  expect_tables_equal(path("first.fits"), path("second.fits"));
  expect_tables_equal(path("first.fits"), path("third.fits"));
  EXPECT_EQ(column(path("first.fits"), "id").size(), static_cast<std::size_t>(kNx * kNy));
}

}  // namespace
