// Shared by the `stampede fit` end-to-end tests: a fixture that runs the binary in a scratch
// directory per test, the GREAT08-mini PSF options, and readers and bitwise comparisons of the
// RESULTS table.
#pragma once

#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <string>
#include <vector>

#include "io/fits_file.hpp"
#include "support/command_runner.hpp"
#include "support/scratch_dir.hpp"

namespace stampede::testing {

class FitCommandTest : public ::testing::Test {
 protected:
  std::string path(const std::string& name) const { return scratch.path(name); }
  RunResult run(std::vector<std::string> args) { return finish(spawn(args, path("stderr.txt")), path("stderr.txt")); }
  ScratchDir scratch{std::string("stampede_fit_") + ::testing::UnitTest::GetInstance()->current_test_info()->name() + "_"};
};

// The Moffat PSF of the GREAT08-mini sets.
inline const std::vector<std::string> kGreat08Psf = {"--set", "psf_beta=3", "--set", "psf_fwhm=2.85",
                                                     "--set", "psf_e1=0",   "--set", "psf_e2=0.05"};

// Writes the first nx x ny stamps (39 px) of the noise-free GREAT08-mini set 0 as a grid image of
// their own: GalSim pixels, cheap to fit.
inline void write_great08_stamps(const std::string& file, int nx, int ny) {
  constexpr int kStamp = 39;
  auto in = io::FitsFile::open_read(std::string(STAMPEDE_DATA_DIR) + "/galsim-great08-mini/nf/set_0.fits");
  std::vector<double> pixels(static_cast<std::size_t>(nx) * kStamp * ny * kStamp);
  in.read_image_region(0, 0, nx * kStamp, ny * kStamp, pixels);
  auto out = io::FitsFile::create(file, true);
  out.write_image(nx * kStamp, ny * kStamp, pixels);
  out.write_key("STAMPSZ", kStamp, "stamp size");
}

// Concatenated arguments (found by `using stampede::testing::operator+`).
inline std::vector<std::string> operator+(std::vector<std::string> a, const std::vector<std::string>& b) {
  a.insert(a.end(), b.begin(), b.end());
  return a;
}

inline std::vector<double> column(const std::string& file, const std::string& name) {
  auto f = io::FitsFile::open_read(file);
  f.move_to("RESULTS");
  return f.read_column(name);
}

// Every column but time_us of a table with grid positions (id ix iy).
inline const std::vector<std::string> kGridResultColumns = {
    "id", "ix", "iy", "x0", "y0", "e1", "e2", "radius", "bulge_A", "disc_A", "bulge_flux", "disc_flux", "flux", "e1_err",
    "e2_err", "snr", "chi2", "likelihood", "n_iter", "n_eval", "stop_reason", "status", "flags", "psf_e1", "psf_e2",
    "psf_fwhm"};

// The named columns of two RESULTS tables are bitwise equal (NaN equals NaN).
inline void expect_tables_equal(const std::string& a, const std::string& b,
                                const std::vector<std::string>& names = kGridResultColumns) {
  auto fa = io::FitsFile::open_read(a);
  fa.move_to("RESULTS");
  ASSERT_EQ(fa.table_rows(), io::FitsFile::open_read(b + "[RESULTS]").table_rows());
  for (const std::string& name : names) {
    const auto x = column(a, name), y = column(b, name);
    ASSERT_EQ(x.size(), y.size()) << name;
    for (std::size_t i = 0; i < x.size(); ++i) {
      const bool same = (std::isnan(x[i]) && std::isnan(y[i])) || std::memcmp(&x[i], &y[i], sizeof(double)) == 0;
      ASSERT_TRUE(same) << name << " row " << i << ": " << x[i] << " vs " << y[i];
    }
  }
}

}  // namespace stampede::testing
