// Tests for the PSFEx reader (io/psfex_file): the sample tile's models evaluated at every cutout's
// position against the PSF stamps its writer drew, a model file written here evaluated against the
// polynomial sum computed independently, and bad files named as they should be.
#include "io/psfex_file.hpp"

#include <fitsio.h>
#include <gtest/gtest.h>

#include <cmath>
#include <string>
#include <vector>

#include "io/fits_file.hpp"
#include "support/error_assertions.hpp"
#include "support/scratch_dir.hpp"

namespace stampede::io {
namespace {

using stampede::testing::Contains;
using stampede::testing::error_of;

const std::string kSample = std::string(STAMPEDE_DATA_DIR) + "/meds-sample";

// The truth's PSF_STAMPS (41 x 41 per cutout, PSF (x) pixel at (20, 20)) against our evaluation at
// the cutout's (x_image, y_image) = (col + 1, row + 1) in its source image.
TEST(PsfexFile, TheSampleModelsGiveTheWritersStamps) {
  FitsFile truth = FitsFile::open_read(kSample + "/truth.fits");
  truth.move_to("CUTOUTS");
  const long long n = truth.table_rows();
  const std::vector<double> x = truth.read_column("x_image"), y = truth.read_column("y_image");
  fitsfile* f = nullptr;
  int status = 0;
  fits_open_file(&f, (kSample + "/truth.fits[PSF_STAMPS]").c_str(), READONLY, &status);
  std::vector<double> stamps(static_cast<std::size_t>(41 * 41 * n));
  int anynul = 0;
  fits_read_img(f, TDOUBLE, 1, static_cast<LONGLONG>(stamps.size()), nullptr, stamps.data(), &anynul, &status);
  fits_close_file(f, &status);
  ASSERT_EQ(status, 0);
  double worst = 0;
  int degree_one = 0;
  std::vector<double> psf(41 * 41);
  for (long long k = 0; k < n; ++k) {
    const PsfexModel m = read_psfex_model(kSample + "/" + truth.read_string("psf_path", k));
    ASSERT_EQ(m.nx, 41);
    degree_one += m.degree == 1;
    std::string error;
    ASSERT_TRUE(m.evaluate(x[k], y[k], psf, &error)) << error;
    const double* want = stamps.data() + k * 41 * 41;
    double peak = 0, sum = 0;
    for (int p = 0; p < 41 * 41; ++p) peak = std::max(peak, want[p]), sum += want[p];
    for (int p = 0; p < 41 * 41; ++p) worst = std::max(worst, std::abs(psf[p] - want[p] / sum) / (peak / sum));
  }
  std::printf("PSFEx at %lld cutouts (%d of degree 1): worst |ours - writer's| = %.2e of the peak\n", n, degree_one, worst);
  EXPECT_GT(degree_one, 0);
  EXPECT_LT(worst, 2e-6);  // the writer's own check of its stamps: 4.6e-7 relative
}

// Must-show 4: a model written here (degree 3, chosen basis) read back and evaluated at chosen
// positions equals the polynomial sum computed term by term in this test.
TEST(PsfexFile, AWrittenModelEvaluatesToTheIndependentPolynomialSum) {
  stampede::testing::ScratchDir dir("stampede_psfex_");
  const std::string path = dir.path("model.psf");
  const int d = 3, nt = 10, nx = 7, ny = 9;
  std::vector<float> cube(static_cast<std::size_t>(nt * nx * ny));
  for (int k = 0; k < nt; ++k)
    for (int p = 0; p < nx * ny; ++p)
      cube[k * nx * ny + p] = static_cast<float>((k == 0 ? 1.0 : 0.05) * std::exp(-0.05 * (p % nx - 3) * (p % nx - 3)) * (1 + 0.3 * std::cos(p + 2 * k)));
  {
    fitsfile* f = nullptr;
    int status = 0;
    fits_create_file(&f, path.c_str(), &status);
    char* ttype[] = {const_cast<char*>("PSF_MASK")};
    const std::string form = std::to_string(nt * nx * ny) + "E";
    char* tform[] = {const_cast<char*>(form.c_str())};
    fits_create_tbl(f, BINARY_TBL, 1, 1, ttype, tform, nullptr, "PSF_DATA", &status);
    auto key_long = [&](const char* k, long v) { fits_update_key(f, TLONG, k, &v, nullptr, &status); };
    auto key_double = [&](const char* k, double v) { fits_update_key(f, TDOUBLE, k, &v, nullptr, &status); };
    auto key_string = [&](const char* k, const char* v) { fits_update_key(f, TSTRING, k, const_cast<char*>(v), nullptr, &status); };
    key_long("POLNAXIS", 2), key_long("POLNGRP", 1), key_long("POLDEG1", d), key_long("PSFNAXIS", 3);
    key_string("POLNAME1", "X_IMAGE"), key_string("POLNAME2", "Y_IMAGE");
    key_double("POLZERO1", 1024.5), key_double("POLZERO2", 2048.5), key_double("POLSCAL1", 2048), key_double("POLSCAL2", 4096);
    key_double("PSF_SAMP", 1.0);
    key_long("PSFAXIS1", nx), key_long("PSFAXIS2", ny), key_long("PSFAXIS3", nt);
    fits_write_col(f, TFLOAT, 1, 1, 1, static_cast<LONGLONG>(cube.size()), cube.data(), &status);
    fits_close_file(f, &status);
    ASSERT_EQ(status, 0);
  }
  const PsfexModel m = read_psfex_model(path);
  ASSERT_EQ(m.degree, d);
  const double positions[3][2] = {{1, 1}, {1500.25, 377.75}, {2048, 4096}};
  for (const auto& pos : positions) {
    const double xs = (pos[0] - 1024.5) / 2048, ys = (pos[1] - 2048.5) / 4096;
    std::vector<double> want(nx * ny, 0.0);
    int k = 0;
    for (int j = 0; j <= d; ++j)
      for (int i = 0; i + j <= d; ++i, ++k)
        for (int p = 0; p < nx * ny; ++p) want[p] += std::pow(xs, i) * std::pow(ys, j) * cube[k * nx * ny + p];
    double sum = 0;
    for (double v : want) sum += v;
    std::vector<double> got(nx * ny);
    std::string error;
    ASSERT_TRUE(m.evaluate(pos[0], pos[1], got, &error)) << error;
    for (int p = 0; p < nx * ny; ++p) EXPECT_NEAR(got[p], want[p] / sum, 1e-14) << p;
  }
}

TEST(PsfexFile, BadFilesAreNamed) {
  EXPECT_TRUE(Contains(error_of<FitsError>([] { read_psfex_model("/nonexistent/se.psf"); }), "/nonexistent/se.psf"));
  const std::string not_psfex = error_of<FitsError>([] { read_psfex_model(kSample + "/meds.fits"); });
  EXPECT_TRUE(Contains(not_psfex, "not a PSFEx model: no HDU 'PSF_DATA'")) << not_psfex;
  stampede::testing::ScratchDir dir("stampede_psfex_");
  const std::string path = dir.path("bad.psf");
  {
    // Degree 1 needs 3 basis images; this file claims degree 2.
    fitsfile* f = nullptr;
    int status = 0;
    const std::string src = kSample + "/psfex/se_e1.psf";
    fits_open_file(&f, src.c_str(), READONLY, &status);
    fitsfile* out = nullptr;
    fits_create_file(&out, path.c_str(), &status);
    fits_copy_file(f, out, 1, 1, 1, &status);
    fits_close_file(f, &status);
    fits_movnam_hdu(out, BINARY_TBL, const_cast<char*>("PSF_DATA"), 0, &status);
    long two = 2;
    fits_update_key(out, TLONG, "POLDEG1", &two, nullptr, &status);
    fits_close_file(out, &status);
    ASSERT_EQ(status, 0);
  }
  const std::string e = error_of<FitsError>([&] { read_psfex_model(path); });
  EXPECT_TRUE(Contains(e, "bad.psf")) << e;
  EXPECT_TRUE(Contains(e, "'PSF_DATA'")) << e;
  EXPECT_TRUE(Contains(e, "PSFAXIS3 = 3 basis images, but POLDEG1 = 2 needs 6")) << e;
}

}  // namespace
}  // namespace stampede::io
