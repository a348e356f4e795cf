// PSF header keywords: a bitwise round trip of both analytic PSFs, GalSim's untyped Moffat keys,
// and the "recorded at all?" probe `stampede fit` uses to compare a set's PSF with the run's.
#include "io/psf_keys.hpp"

#include <gtest/gtest.h>

#include <filesystem>
#include <string>
#include <vector>

#include "io/fits_error.hpp"
#include "io/fits_file.hpp"
#include "support/error_assertions.hpp"
#include "support/scratch_dir.hpp"

namespace stampede::io {
namespace {

namespace fs = std::filesystem;
using stampede::testing::Contains;
using stampede::testing::error_of;

class PsfKeysTest : public ::testing::Test {
 protected:
  // A one-pixel image HDU with `write` applied to its header.
  template <class Write>
  std::string image_with(const std::string& name, Write write) {
    const std::string p = scratch.path(name);
    auto f = FitsFile::create(p, true);
    f.write_image(1, 1, std::vector<double>{0.0});
    write(f);
    return p;
  }
  stampede::testing::ScratchDir scratch{"stampede_psfkeys_"};
};

TEST_F(PsfKeysTest, AnalyticPsfsRoundTripBitwise) {
  PsfModel moffat;
  moffat.kind = PsfKind::kMoffat;
  moffat.moffat = {3.5, 2.85, -0.0123456789012345, 0.05, 4.25};
  PsfModel airy;
  airy.kind = PsfKind::kAiry;
  airy.airy = {1.7, 0.3};
  auto f = FitsFile::open_read(image_with("moffat.fits", [&](FitsFile& g) { write_psf_keys(g, moffat); }));
  const std::optional<PsfModel> m = read_psf_keys_if_present(f);
  ASSERT_TRUE(m.has_value());
  EXPECT_EQ(m->kind, PsfKind::kMoffat);
  EXPECT_EQ(m->moffat.beta, moffat.moffat.beta);
  EXPECT_EQ(m->moffat.fwhm, moffat.moffat.fwhm);
  EXPECT_EQ(m->moffat.e1, moffat.moffat.e1);
  EXPECT_EQ(m->moffat.e2, moffat.moffat.e2);
  EXPECT_EQ(m->moffat.truncation, moffat.moffat.truncation);
  auto g = FitsFile::open_read(image_with("airy.fits", [&](FitsFile& h) { write_psf_keys(h, airy); }));
  const std::optional<PsfModel> a = read_psf_keys_if_present(g);
  ASSERT_TRUE(a.has_value());
  EXPECT_EQ(a->kind, PsfKind::kAiry);
  EXPECT_EQ(a->airy.lambda_over_d, 1.7);
  EXPECT_EQ(a->airy.obscuration, 0.3);
}

TEST_F(PsfKeysTest, GalSimSetsRecordAnUntypedMoffat) {
  auto f = FitsFile::open_read(image_with("galsim.fits", [](FitsFile& g) {
    g.write_key("PSFBETA", 3.0, "");
    g.write_key("PSFFWHM", 2.85, "");
    g.write_key("PSFE1", 0.0, "");
    g.write_key("PSFE2", 0.05, "");
  }));
  const std::optional<PsfModel> m = read_psf_keys_if_present(f);
  ASSERT_TRUE(m.has_value());
  EXPECT_EQ(m->kind, PsfKind::kMoffat);
  EXPECT_EQ(m->moffat.e2, 0.05);
  EXPECT_EQ(m->moffat.truncation, 0.0);
}

TEST_F(PsfKeysTest, NoPsfKeysMeansNothingRecorded) {
  auto f = FitsFile::open_read(image_with("plain.fits", [](FitsFile& g) { g.write_key("STAMPSZ", 9, ""); }));
  EXPECT_FALSE(read_psf_keys_if_present(f).has_value());
}

TEST_F(PsfKeysTest, AnIncompleteRecordIsAnErrorNamingTheFileAndKey) {
  const std::string p = image_with("partial.fits", [](FitsFile& g) {
    g.write_key("PSFTYPE", std::string("moffat"), "");
    g.write_key("PSFBETA", 3.0, "");
  });
  auto f = FitsFile::open_read(p);
  const std::string error = error_of<FitsError>([&] { read_psf_keys_if_present(f); });
  EXPECT_TRUE(Contains(error, "partial.fits"));
  EXPECT_TRUE(Contains(error, "PSFFWHM"));
}

}  // namespace
}  // namespace stampede::io
