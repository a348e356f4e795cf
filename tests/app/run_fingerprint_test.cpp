// The run fingerprint: FNV-1a 64 in hex, and the exact identities of `fit` and `calibrate build`
// pinned to the values the builders before app/ wrote, so partial outputs they left still resume.
#include <gtest/gtest.h>

#include "app/run_fingerprint.hpp"

namespace {

using stampede::app::RunFingerprint;

TEST(RunFingerprint, IsFnv1a64InHex) {
  EXPECT_EQ(RunFingerprint().hex(), "14650fb0739d0383");  // the offset basis: nothing hashed
  EXPECT_EQ(RunFingerprint().text("abc").hex(), "e16801510db89efd");
  EXPECT_EQ(RunFingerprint().text("a").text("bc").hex(), RunFingerprint().text("abc").hex());
  EXPECT_EQ(RunFingerprint().line("x").hex(), RunFingerprint().text("x\n").hex());
  EXPECT_EQ(RunFingerprint().number(0.8).hex(), RunFingerprint().text("0.80000000000000004").hex());
  EXPECT_EQ(RunFingerprint().integer(-17).hex(), RunFingerprint().text("-17").hex());
  EXPECT_EQ(RunFingerprint().options({{"a", "1"}, {"b", ""}}).hex(), RunFingerprint().text("a=1\nb=\n").hex());
}

TEST(RunFingerprint, FitIdentityIsUnchanged) {
  const std::vector<std::pair<std::string, std::string>> header = {
      {"stamp_size", "39"}, {"psf_fwhm", "2.85"}, {"INPUT", "in.fits"}, {"CATALOG", "cat.txt"}};
  EXPECT_EQ(stampede::app::fit_fingerprint("in.fits", "cat.txt", "", header), "a079c572e51b0c3e");
  // Every part counts, including which of the paths a name is given as.
  EXPECT_NE(stampede::app::fit_fingerprint("in.fits", "", "cat.txt", header), "a079c572e51b0c3e");
  auto other = header;
  other[1].second = "2.86";
  EXPECT_NE(stampede::app::fit_fingerprint("in.fits", "cat.txt", "", other), "a079c572e51b0c3e");
}

TEST(RunFingerprint, CalibrationBuildIdentityIsUnchanged) {
  stampede::CalibrationGridOptions g;  // the defaults: radii 1,2.5,5; F 0,0.5,1; S/N 20; e 0.8 in 17; 16 pairs; seed 11
  const std::vector<std::pair<std::string, std::string>> config = {{"stamp_size", "39"}, {"noise_sigma", "1"}};
  EXPECT_EQ(stampede::app::calibration_build_fingerprint(g, config), "95c65930505f280d");
  g.seed = 12;
  EXPECT_NE(stampede::app::calibration_build_fingerprint(g, config), "95c65930505f280d");
}

}  // namespace
