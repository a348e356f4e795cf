// The calibration file: a bitwise round trip of the grid, points, curves and configuration, the
// extended-table helpers it and `calibrate apply` use, and errors that name the file and key.
#include "io/calibration_table.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <string>

#include "io/fits_file.hpp"
#include "support/error_assertions.hpp"
#include "support/scratch_dir.hpp"

namespace stampede::io {
namespace {

namespace fs = std::filesystem;
using stampede::testing::Contains;
using stampede::testing::error_of;

class CalibrationTableTest : public ::testing::Test {
 protected:
  std::string path(const std::string& name) const { return scratch.path(name); }
  stampede::testing::ScratchDir scratch{"stampede_caltable_"};
};

CalibrationTable sample_table() {
  CalibrationTable t;
  t.grid.radii = {1.0, 2.5, 5.0};
  t.grid.bulge_fractions = {0.0, 0.5, 1.0};
  t.grid.e_steps = 5;
  t.grid.e_max = 0.7;
  t.grid.snr = 17.5;
  t.grid.noise_sigma = 0.3;
  t.grid.realisations = 8;
  t.grid.stamp_size = 33;
  t.grid.bulge_radius_ratio = 0.8;
  t.grid.seed = 99;
  t.grid.psf.moffat = {3.5, 2.7, 0.01, -0.04, 6.0};
  const CalibrationGrid grid(t.grid);
  t.points = grid.points();
  for (std::size_t i = 0; i < t.points.size(); ++i) {
    PointBias b;
    b.bias[0] = 0.001 * std::sin(static_cast<double>(i));
    b.error[0] = 1e-4 / (1.0 + static_cast<double>(i));
    b.bias[1] = i == 3 ? NAN : -0.002 * std::cos(static_cast<double>(i));
    b.error[1] = 3e-4;
    b.pairs_used = 8 - static_cast<int>(i % 3);
    b.pairs_failed = static_cast<int>(i % 3);
    t.biases.push_back(b);
  }
  t.curves = fit_bias_curves(t.grid, t.points, t.biases);
  t.config = {{"upsampling", "5"}, {"noise_sigma", "0.3"}, {"x0_start", "auto"}, {"psf_image", ""}};
  return t;
}

TEST_F(CalibrationTableTest, RoundTripIsBitwise) {
  const CalibrationTable t = sample_table();
  write_calibration_table(path("cal.fits"), t, false);
  const CalibrationTable r = read_calibration_table(path("cal.fits"));
  EXPECT_EQ(r.grid.radii, t.grid.radii);
  EXPECT_EQ(r.grid.bulge_fractions, t.grid.bulge_fractions);
  EXPECT_EQ(r.grid.e_steps, 5);
  EXPECT_EQ(r.grid.e_max, 0.7);
  EXPECT_EQ(r.grid.snr, 17.5);
  EXPECT_EQ(r.grid.noise_sigma, 0.3);
  EXPECT_EQ(r.grid.realisations, 8);
  EXPECT_EQ(r.grid.stamp_size, 33);
  EXPECT_EQ(r.grid.bulge_radius_ratio, 0.8);
  EXPECT_EQ(r.grid.seed, 99u);
  EXPECT_EQ(r.grid.psf.kind, PsfKind::kMoffat);
  EXPECT_EQ(r.grid.psf.moffat.beta, 3.5);
  EXPECT_EQ(r.grid.psf.moffat.e2, -0.04);
  EXPECT_EQ(r.grid.psf.moffat.truncation, 6.0);
  ASSERT_EQ(r.points.size(), t.points.size());
  for (std::size_t i = 0; i < t.points.size(); ++i) {
    EXPECT_EQ(r.points[i].index, t.points[i].index);
    EXPECT_EQ(r.points[i].radius, t.points[i].radius);
    EXPECT_EQ(r.points[i].axis, t.points[i].axis);
    EXPECT_EQ(r.points[i].e_true, t.points[i].e_true);
    EXPECT_EQ(r.biases[i].bias[0], t.biases[i].bias[0]);
    EXPECT_EQ(r.biases[i].error[0], t.biases[i].error[0]);
    if (i == 3) {
      EXPECT_TRUE(std::isnan(r.biases[i].bias[1]));
    } else {
      EXPECT_EQ(r.biases[i].bias[1], t.biases[i].bias[1]);
    }
    EXPECT_EQ(r.biases[i].pairs_used, t.biases[i].pairs_used);
    EXPECT_EQ(r.biases[i].pairs_failed, t.biases[i].pairs_failed);
  }
  ASSERT_EQ(r.curves.size(), 36u);
  for (std::size_t k = 0; k < t.curves.size(); ++k) {
    EXPECT_EQ(r.curves[k].axis, t.curves[k].axis);
    EXPECT_EQ(r.curves[k].component, t.curves[k].component);
    EXPECT_EQ(r.curves[k].points, t.curves[k].points);
    for (int j = 0; j < 4; ++j) {
      EXPECT_EQ(r.curves[k].coefficients[j], t.curves[k].coefficients[j]);
      EXPECT_EQ(r.curves[k].errors[j], t.curves[k].errors[j]);
    }
  }
  EXPECT_EQ(r.config, t.config);
  // The model built from the file is the model built from memory.
  const NoiseBiasModel a(t), b(r);
  EXPECT_EQ(a.at({2.0, 0.3, 0.4}).m, b.at({2.0, 0.3, 0.4}).m);
  EXPECT_EQ(b.psf_e0(), std::complex<double>(0.01, -0.04));
  // No silent replacement.
  EXPECT_TRUE(Contains(error_of<std::runtime_error>([&] { write_calibration_table(path("cal.fits"), t, false); }), "cal.fits"));
}

TEST_F(CalibrationTableTest, OtherFilesAreRefusedNamingTheKey) {
  {
    FitsFile f = FitsFile::create(path("other.fits"), false);
    f.write_empty_image();
    f.write_key("CALIBVER", 7LL, "");
  }
  const std::string e = error_of<std::runtime_error>([&] { read_calibration_table(path("other.fits")); });
  EXPECT_TRUE(Contains(e, "other.fits"));
  EXPECT_TRUE(Contains(e, "CALIBVER 7"));
  {
    FitsFile f = FitsFile::create(path("empty.fits"), false);
    f.write_empty_image();
  }
  EXPECT_TRUE(Contains(error_of<std::runtime_error>([&] { read_calibration_table(path("empty.fits")); }), "CALIBVER"));
  EXPECT_TRUE(Contains(error_of<std::runtime_error>([&] { read_calibration_table(path("missing.fits")); }), "missing.fits"));
}

// Found while writing fuzz_calibration_table: integers beyond the int range went through static_cast<int>,
// a wrapped NREAL passing validation and a 2^40 pairs count being undefined behaviour.
TEST_F(CalibrationTableTest, IntegersBeyondTheIntRangeAreRefusedNamingTheKeyOrRow) {
  write_calibration_table(path("cal.fits"), sample_table(), false);
  auto altered = [&](const std::string& name, auto change) {
    FitsFile in = FitsFile::open_read(path("cal.fits"));
    FitsFile out = FitsFile::create(path(name), false);
    in.copy_all_hdus_to(out);
    change(out);
    out.close();
    return path(name);
  };
  const std::string nreal = altered("nreal.fits", [](FitsFile& f) {
    f.move_to(0);
    f.write_key("NREAL", 4294967304LL, "");
  });
  EXPECT_TRUE(Contains(error_of<FitsError>([&] { read_calibration_table(nreal); }),
                       "header keyword 'NREAL' = 4294967304 is out of range"));
  const std::string used = altered("used.fits", [](FitsFile& f) {
    f.move_to("POINTS");
    const double v[] = {1099511627776.0};
    f.write_column_rows("pairs_used", 2, v);
  });
  EXPECT_TRUE(Contains(error_of<FitsError>([&] { read_calibration_table(used); }),
                       "'POINTS']: row 3: column 'pairs_used' = 1099511627776 is not an integer"));
  const std::string axis = altered("axis.fits", [](FitsFile& f) {
    f.move_to("CURVES");
    const double v[] = {7.0};
    f.write_column_rows("axis", 0, v);
  });
  EXPECT_TRUE(Contains(error_of<FitsError>([&] { read_calibration_table(axis); }),
                       "row 1: column 'axis' = 7 is neither 0 (e1) nor 1 (e2)"));
}

TEST_F(CalibrationTableTest, CopiedTableTakesNewColumns) {
  {
    FitsFile f = FitsFile::create(path("in.fits"), false);
    f.write_empty_image();
    f.write_table("RESULTS", {{"id", true, {1, 2, 3}}, {"e1", false, {0.1, 0.2, 0.3}}});
  }
  {
    FitsFile in = FitsFile::open_read(path("in.fits"));
    FitsFile out = FitsFile::create(path("out.fits"), false);
    in.copy_all_hdus_to(out);
    out.move_to("RESULTS");
    out.add_column("e1_cal", "calibrated");
    const double v[] = {1.5, 2.5};
    out.write_column_rows("e1_cal", 1, v);
    EXPECT_TRUE(Contains(error_of<std::runtime_error>([&] { out.add_column("e1", ""); }), "has one"));
    out.close();
  }
  FitsFile r = FitsFile::open_read(path("out.fits"));
  r.move_to("RESULTS");
  EXPECT_EQ(r.read_column("e1"), (std::vector<double>{0.1, 0.2, 0.3}));
  const auto cal = r.read_column("e1_cal");
  ASSERT_EQ(cal.size(), 3u);
  EXPECT_EQ(cal[1], 1.5);
  EXPECT_EQ(cal[2], 2.5);
  EXPECT_EQ(r.key_string("TCOMM3"), "calibrated");
}

}  // namespace
}  // namespace stampede::io
