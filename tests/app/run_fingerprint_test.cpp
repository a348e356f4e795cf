// The run fingerprint: FNV-1a 64 in hex; the exact text of `fit`'s (program version, each input's
// size and XXH64, the options), which any change of an input's content changes; and the pinned hash
// of `calibrate build` (its grid, configuration and the program version).
#include <gtest/gtest.h>

#include <fstream>

#include "app/run_fingerprint.hpp"
#include "app/version.hpp"
#include "io/durable_file.hpp"
#include "support/scratch_dir.hpp"

namespace {

using stampede::app::fit_fingerprint;
using stampede::app::FingerprintFile;
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

TEST(RunFingerprint, FitIdentityCoversVersionContentsAndOptions) {
  stampede::testing::ScratchDir dir("stampede_run_fingerprint_");
  const std::string in = dir.path("in.fits"), cat = dir.path("cat.txt");
  std::ofstream(in, std::ios::binary) << "abc";
  std::ofstream(cat, std::ios::binary) << "";
  const std::vector<std::pair<std::string, std::string>> header = {{"stamp_size", "39"}, {"INPUT", in}};
  const std::vector<FingerprintFile> files = {{"input", in}, {"catalog", cat}};
  // The exact text (the checkpoint records it): XXH64("abc") and XXH64("") as in file_digest_test.
  const std::string expected = "stampede " + std::string(stampede::app::program_version()) + "\n" +
                               "input " + in + ": 3 bytes, xxh64 44bc2cf5ad770999\n" +
                               "catalog " + cat + ": 0 bytes, xxh64 ef46db3751d8e999\n" +
                               "stamp_size=39\nINPUT=" + in + "\n";
  EXPECT_EQ(fit_fingerprint(files, header), expected);
  // CFITSIO syntax names the same file on disk: the same content line.
  EXPECT_NE(fit_fingerprint({{"input", in + "[0]"}}, {}).find(": 3 bytes, xxh64 44bc2cf5ad770999\n"), std::string::npos);
  // The content at the same path, the same size: another run.
  std::ofstream(in, std::ios::binary) << "abd";
  EXPECT_NE(fit_fingerprint(files, header), expected);
  std::ofstream(in, std::ios::binary) << "abc";
  EXPECT_EQ(fit_fingerprint(files, header), expected);
  // Which role a file has, and every option, count too.
  EXPECT_NE(fit_fingerprint({{"input", in}, {"weight", cat}}, header), expected);
  auto other = header;
  other[0].second = "40";
  EXPECT_NE(fit_fingerprint(files, other), expected);
  // A file that cannot be read is an error naming it.
  EXPECT_THROW(fit_fingerprint({{"input", dir.path("gone.fits")}}, header), stampede::io::FileError);
}

TEST(RunFingerprint, CalibrationBuildIdentityIsTheDocumentedBytes) {
  stampede::CalibrationGridOptions g;  // the defaults: radii 1,2.5,5; F 0,0.5,1; S/N 20; e 0.8 in 17; 16 pairs; seed 11
  const std::vector<std::pair<std::string, std::string>> config = {{"stamp_size", "39"}, {"noise_sigma", "1"}};
  const std::string bytes = "stampede " + std::string(stampede::app::program_version()) +
                            "\n1,2.5,5,0,0.5,1,|20|0.80000000000000004|17|16|11|stamp_size=39\nnoise_sigma=1\n";
  const std::string expected = RunFingerprint().text(bytes).hex();
  EXPECT_EQ(stampede::app::calibration_build_fingerprint(g, config), expected);
  // Before the program version was part of it: the grid and configuration alone.
  EXPECT_NE(expected, "95c65930505f280d");
  EXPECT_EQ(RunFingerprint().text(bytes.substr(bytes.find('\n') + 1)).hex(), "95c65930505f280d");
  g.seed = 12;
  EXPECT_NE(stampede::app::calibration_build_fingerprint(g, config), expected);
}

}  // namespace
