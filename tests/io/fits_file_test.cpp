// Tests for io/fits_file: reading the shared GalSim reference files (images, headers, tables),
// CFITSIO extended syntax and gzip input, bitwise write/read round trips, and that every failure
// is a FitsError naming the file, HDU and keyword or column.
#include "io/fits_file.hpp"

#include <fitsio.h>
#include <gtest/gtest.h>

#include "support/error_assertions.hpp"
#include "support/header_card_edit.hpp"
#include "support/scratch_dir.hpp"

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <iterator>
#include <limits>
#include <numeric>
#include <string>
#include <utility>
#include <vector>

namespace stampede::io {
namespace {

using stampede::testing::Contains;
using stampede::testing::error_of;

namespace fs = std::filesystem;

const std::string kData = STAMPEDE_DATA_DIR;
const std::string kSet0 = kData + "/galsim-great08-mini/nf/set_0.fits";
const std::string kTruth0 = kData + "/galsim-great08-mini/nf/truth_0.fits";
const std::string kCases = kData + "/galsim-reference/render_cases.fits";

bool bitwise_equal(const std::vector<double>& a, const std::vector<double>& b) {
  return a.size() == b.size() &&
         (a.empty() || std::memcmp(a.data(), b.data(), a.size() * sizeof(double)) == 0);
}

// A fresh private directory per test, removed afterwards, so parallel ctest runs cannot collide.
class FitsFileTmp : public ::testing::Test {
 protected:
  std::string tmp(const std::string& name) const { return scratch_.path(name); }

  stampede::testing::ScratchDir scratch_{"stampede_io_"};
};

// --- reading the reference data ------------------------------------------------------------------

// A URL is not a file on disk: refused before CFITSIO is given it (no network access, no leak in
// its parse of an unknown scheme); a file:// path is a file.
TEST(FitsFileRead, AUrlIsRefusedByName) {
  for (const std::string url : {"http://example.invalid/a.fits", "ftp://example.invalid/a.fits", "met://rics/minus.fits",
                                "mem://x", "ftp:20", "stdin", "/tmp/a/sta://de/b.fits", "~no_such_user_x/a.fits",
                                " ~no_such_user_x/a.fits", "  ftp:21", "file://~no_such_user_x/a.fits",
                                "\t\tfile://\t/tmp/a.fits", "a\nb.fits", "file://a://b.fits"}) {
    try {
      FitsFile::open_read(url);
      ADD_FAILURE() << url << " was opened";
    } catch (const FitsError& e) {
      EXPECT_NE(std::string(e.what()).find("'" + url + "': a URL, a device or a name with control characters"),
                std::string::npos) << e.what();
    }
    EXPECT_THROW(FitsFile::create(url, true), FitsError) << url;
  }
}

// CFITSIO reads "in.fits(out.fits)" as a copy to out.fits: a read would write a file. Refused,
// nothing written (found by probing after fuzz finding F17).
TEST(FitsFileRead, CfitsiosCopySyntaxIsRefusedAndWritesNothing) {
  const stampede::testing::ScratchDir dir("stampede_fits_copy_");
  const std::string copy = dir.path("copy.fits");
  const std::string name = kSet0 + "(" + copy + ")";
  try {
    FitsFile::open_read(name);
    ADD_FAILURE() << name << " was opened";
  } catch (const FitsError& e) {
    EXPECT_NE(std::string(e.what()).find("'(' in a name is CFITSIO's input(output) copy"), std::string::npos) << e.what();
  }
  EXPECT_FALSE(std::filesystem::exists(copy));
  EXPECT_THROW(FitsFile::open_read(kSet0 + "(~no_such_user_x)"), FitsError);
  EXPECT_THROW(FitsFile::create(dir.path("a.fits(b.fits)"), true), FitsError);
}

// Brackets select an HDU and nothing else: CFITSIO's binning ("[bin x=0:1:1e-9]" asked for 8 GB),
// row filters and column expressions would read other bytes than the file's.
TEST(FitsFileRead, BracketsSelectAnHduAndNoFilter) {
  EXPECT_NO_THROW(FitsFile::open_read(kSet0 + "[0]"));
  EXPECT_NO_THROW(FitsFile::open_read(kSet0 + "[PRIMARY]"));
  for (const std::string spec : {"[0][bin x=0:1:1e-9]", "[1][e1>0]", "[1][col e1=1]", "[bin x]", "[]", "[0", "[A,1,2]",
                                 "[-f-.te.]", "[A,]", "[_x]", "[1a]"}) {
    try {
      FitsFile::open_read(kSet0 + spec);
      ADD_FAILURE() << spec << " was opened";
    } catch (const FitsError& e) {
      EXPECT_NE(std::string(e.what()).find("brackets select an HDU only"), std::string::npos) << spec << ": " << e.what();
    }
  }
}

// Found by the fuzz campaign (F19, fuzz_cell_image): NAXIS1 = 2^63 - 1 overflowed CFITSIO's end
// of data, and the reader asked for 2^63 doubles (std::length_error, an abort). Pixels a file cannot
// hold are a FitsError naming the sizes.
TEST(FitsFileRead, AnImageLargerThanItsFileIsAnErrorNotAnAllocation) {
  const stampede::testing::ScratchDir dir("stampede_fits_huge_");
  const std::string path = dir.path("huge.fits");
  {
    FitsFile f = FitsFile::create(path, true);
    f.write_image(4, 4, std::vector<double>(16, 1.0));
  }
  stampede::testing::replace_card(path, "NAXIS1  = ", "NAXIS1  =  9223372036854775807 / length of data axis 1");
  try {
    FitsFile f = FitsFile::open_read(path);
    f.read_image();
    ADD_FAILURE() << "a 2^63 - 1 pixel image was read";
  } catch (const FitsError& e) {
    EXPECT_NE(std::string(e.what()).find("cannot be in a file of"), std::string::npos) << e.what();
  }
}

TEST(FitsFileRead, Great08SetShapeAndHeader) {
  FitsFile f = FitsFile::open_read(kSet0);
  EXPECT_EQ(f.path(), kSet0);
  EXPECT_EQ(f.hdu_count(), 1);
  EXPECT_EQ(f.hdu_index(), 0);
  const auto shape = f.image_shape();
  EXPECT_EQ(shape.nx, 780);
  EXPECT_EQ(shape.ny, 780);
  EXPECT_EQ(f.hdu_index(), 0);  // the primary holds the image: no automatic move
  EXPECT_EQ(f.key_long("STAMPSZ"), 39);
  EXPECT_EQ(f.key_long("GRIDNX"), 20);
  EXPECT_EQ(f.key_long("GRIDNY"), 20);
  EXPECT_DOUBLE_EQ(f.key_double("PSFBETA"), 3.0);
  EXPECT_DOUBLE_EQ(f.key_double("PSFE2"), 0.05);
  EXPECT_DOUBLE_EQ(f.key_double("PSFFWHM"), 2.85);
  EXPECT_DOUBLE_EQ(f.key_double("STAMPSZ"), 39.0);  // integer value read as a double
  EXPECT_EQ(f.key_long("PSFBETA"), 3);              // integral float read as an integer
  EXPECT_EQ(f.key_long("stampsz"), 39);             // keyword names are case-insensitive
  EXPECT_EQ(f.key_string("SIZEDEF"), "fwhm");       // trailing blanks dropped
  EXPECT_EQ(f.key_string("STAMPSZ"), "39");         // non-strings as written
  EXPECT_EQ(f.read_key_double("NOSUCHKY"), std::nullopt);
  EXPECT_EQ(f.read_key_long("NOSUCHKY"), std::nullopt);
  EXPECT_EQ(f.read_key_string("NOSUCHKY"), std::nullopt);
  EXPECT_EQ(f.read_key_long("GRIDNY"), 20);
}

TEST(FitsFileRead, Great08PixelsAndRowStrips) {
  FitsFile f = FitsFile::open_read(kSet0);
  const std::vector<double> image = f.read_image();
  ASSERT_EQ(image.size(), 780u * 780u);
  // float32 pixels, exactly as astropy reads them: row-major, x fastest.
  EXPECT_EQ(image[0], 0.009204968810081482);
  EXPECT_EQ(image[1], 0.010613192804157734);                // (x, y) = (1, 0)
  EXPECT_EQ(image[780], 0.009376173838973045);              // (x, y) = (0, 1)
  EXPECT_EQ(image[100 * 780 + 5], 0.03425123915076256);     // (x, y) = (5, 100)
  EXPECT_EQ(image[5 * 780 + 100], 0.00138541916385293);     // (x, y) = (100, 5)
  EXPECT_EQ(image[19 * 780 + 19], 10.731636047363281);      // centre of stamp (0, 0)
  EXPECT_EQ(*std::max_element(image.begin(), image.end()), 12.630799293518066);

  // Stamp row iy = 10 (rows 390..428), the last stamp row, and a single row.
  for (const auto& [y0, rows] : {std::pair{390L, 39L}, std::pair{741L, 39L}, std::pair{5L, 1L}}) {
    std::vector<double> strip(static_cast<std::size_t>(rows * 780));
    f.read_image_rows(y0, rows, strip);
    const std::vector<double> expected(image.begin() + y0 * 780, image.begin() + (y0 + rows) * 780);
    EXPECT_TRUE(bitwise_equal(strip, expected)) << "rows from " << y0;
  }
  std::vector<double> none;
  EXPECT_NO_THROW(f.read_image_rows(780, 0, none));  // empty range at the end is valid
}

TEST(FitsFileRead, RenderCasesTableAndImages) {
  FitsFile f = FitsFile::open_read(kCases);
  EXPECT_EQ(f.hdu_count(), 24);
  f.move_to("CASES");
  EXPECT_EQ(f.hdu_index(), 23);
  EXPECT_TRUE(Contains(f.describe(), "render_cases.fits[HDU 23 'CASES']"));
  EXPECT_EQ(f.table_rows(), 22);
  EXPECT_TRUE(f.has_column("hlr"));
  EXPECT_TRUE(f.has_column("HLR"));  // case-insensitive, as CFITSIO
  EXPECT_FALSE(f.has_column("hl*"));  // no wildcard matching
  EXPECT_FALSE(f.has_column("radius"));

  const std::vector<double> hlr = f.read_column("hlr");
  ASSERT_EQ(hlr.size(), 22u);
  EXPECT_DOUBLE_EQ(hlr[0], 0.8);
  EXPECT_DOUBLE_EQ(hlr[4], 3.0);
  EXPECT_DOUBLE_EQ(hlr[18], 1.2);
  EXPECT_DOUBLE_EQ(hlr[21], 0.3);
  const std::vector<double> stamp = f.read_column("stamp");  // TFORM J, converted to double
  ASSERT_EQ(stamp.size(), 22u);
  EXPECT_EQ(stamp[0], 39.0);
  EXPECT_EQ(stamp[18], 25.0);
  EXPECT_EQ(stamp[19], 48.0);
  const std::vector<double> cases = f.read_column("case");
  for (std::size_t i = 0; i < cases.size(); ++i) EXPECT_EQ(cases[i], static_cast<double>(i));
  const double stamp_sum0 = f.read_column("stamp_sum")[0];

  f.move_to("CASE19");
  EXPECT_EQ(f.hdu_index(), 20);
  EXPECT_TRUE(Contains(f.describe(), "render_cases.fits[HDU 20 'CASE19']"));
  auto shape = f.image_shape();
  EXPECT_EQ(shape.nx, 48);
  EXPECT_EQ(shape.ny, 48);
  f.move_to(19);  // by index: CASE18, the 25-pixel stamp
  shape = f.image_shape();
  EXPECT_EQ(shape.nx, 25);
  EXPECT_EQ(shape.ny, 25);

  f.move_to("case00");  // EXTNAME matching is case-insensitive
  EXPECT_EQ(f.hdu_index(), 1);
  const std::vector<double> pixels = f.read_image();
  ASSERT_EQ(pixels.size(), 39u * 39u);
  const double sum = std::accumulate(pixels.begin(), pixels.end(), 0.0);
  EXPECT_NEAR(sum, stamp_sum0, 1e-9 * std::abs(stamp_sum0));
  EXPECT_NEAR(stamp_sum0, 999.7091394507572, 1e-9);
}

TEST(FitsFileRead, AutoMovesToFirstImageOnlyUntilMovedExplicitly) {
  {
    // The primary of render_cases.fits is empty: image functions go to CASE00 (HDU 1).
    FitsFile f = FitsFile::open_read(kCases);
    EXPECT_EQ(f.hdu_index(), 0);
    EXPECT_EQ(f.key_string("SIMPLE"), "T");  // header reads stay on the primary
    const auto shape = f.image_shape();
    EXPECT_EQ(shape.nx, 39);
    EXPECT_EQ(f.hdu_index(), 1);
    EXPECT_EQ(f.key_string("EXTNAME"), "CASE00");
  }
  {
    // CFITSIO's "[n]" syntax selects the HDU itself; it must not be overridden.
    FitsFile f = FitsFile::open_read(kCases + "[19]");
    EXPECT_EQ(f.hdu_index(), 19);
    EXPECT_EQ(f.image_shape().nx, 25);
    EXPECT_EQ(f.hdu_index(), 19);
  }
  {
    // An explicit move to the empty primary is respected, so image functions fail there.
    FitsFile f = FitsFile::open_read(kCases);
    f.move_to(0);
    const std::string msg = error_of<FitsError>([&] { f.image_shape(); });
    EXPECT_TRUE(Contains(msg, "render_cases.fits[HDU 0]"));
    EXPECT_TRUE(Contains(msg, "not a 2-D image"));
  }
}

TEST(FitsFileRead, TruthHeaderAndTable) {
  FitsFile f = FitsFile::open_read(kTruth0);
  EXPECT_DOUBLE_EQ(f.key_double("SHEAR1"), 0.02978591868433564);
  EXPECT_TRUE(f.read_key_double("SHEAR2").has_value());
  f.move_to("TRUTH");
  EXPECT_EQ(f.hdu_index(), 1);
  EXPECT_EQ(f.table_rows(), 400);
  EXPECT_TRUE(f.has_column("e1_obs"));
  const std::vector<double> e1 = f.read_column("e1_obs");
  ASSERT_EQ(e1.size(), 400u);
  for (double e : e1) EXPECT_LT(std::abs(e), 1.0);
  const std::vector<double> index = f.read_column("index");
  ASSERT_EQ(index.size(), 400u);
  EXPECT_EQ(index[0], 0.0);
  EXPECT_EQ(index[399], 399.0);
}

TEST(FitsFileRead, ExtendedSyntaxOpensOnTable) {
  const std::string path = kCases + "[CASES]";
  FitsFile f = FitsFile::open_read(path);
  EXPECT_EQ(f.path(), path);
  EXPECT_EQ(f.hdu_index(), 23);
  EXPECT_EQ(f.table_rows(), 22);
  EXPECT_EQ(f.read_column("hlr")[18], 1.2);
  // Messages name the file without the bracketed selector.
  EXPECT_TRUE(Contains(f.describe(), "render_cases.fits[HDU 23 'CASES']"));
  EXPECT_FALSE(Contains(f.describe(), "[CASES]"));
}

TEST_F(FitsFileTmp, GzipCopyReadsTheSamePixels) {
  const std::string gz = tmp("set_0.fits.gz");
  const std::string cmd = "gzip -c '" + kSet0 + "' > '" + gz + "'";
  ASSERT_EQ(std::system(cmd.c_str()), 0) << cmd;
  FitsFile plain = FitsFile::open_read(kSet0);
  FitsFile packed = FitsFile::open_read(gz);
  EXPECT_EQ(packed.key_long("STAMPSZ"), 39);
  EXPECT_TRUE(bitwise_equal(packed.read_image(), plain.read_image()));
  std::vector<double> a(780 * 3);
  std::vector<double> b(780 * 3);
  packed.read_image_rows(400, 3, a);
  plain.read_image_rows(400, 3, b);
  EXPECT_TRUE(bitwise_equal(a, b));
}

// --- writing ---------------------------------------------------------------------------------------

TEST_F(FitsFileTmp, RoundTripIsBitwise) {
  const std::string path = tmp("round_trip.fits");
  const long nx = 7;
  const long ny = 5;
  std::vector<double> pixels(nx * ny);
  for (std::size_t i = 0; i < pixels.size(); ++i) pixels[i] = std::sin(0.37 * i) / 3.0;
  pixels[3] = -0.0;
  pixels[4] = std::numeric_limits<double>::denorm_min();
  pixels[5] = std::numeric_limits<double>::max();
  pixels[6] = std::numeric_limits<double>::quiet_NaN();
  const std::vector<double> second = {1.0, 2.0, 3.0, 4.0, 5.0, 6.0};
  const std::string long_text(150, 'x');
  {
    FitsFile f = FitsFile::create(path, /*overwrite=*/false);
    f.write_image(nx, ny, pixels, "STAMP");
    f.write_key("GAIN", 0.1, "a value with no short decimal form");
    f.write_key("TINY", 1e-300, "");
    f.write_key("BIGINT", 9007199254740993LL, "2^53 + 1, not representable as a double");
    f.write_key("NEG", -42, "via the integral-type overload");
    f.write_key("OBJECT", std::string("it's a test"), "quote inside");
    f.write_key("LONGTXT", long_text, "needs CONTINUE cards");
    f.write_key("GAIN", 1.0 / 3.0, "updated in place");
    f.write_image(3, 2, second, "SECOND");
    EXPECT_EQ(f.hdu_index(), 1);
    f.close();
  }
  FitsFile f = FitsFile::open_read(path);
  EXPECT_EQ(f.hdu_count(), 2);
  f.move_to("STAMP");
  EXPECT_EQ(f.hdu_index(), 0);  // the first image of a new file is the primary
  EXPECT_EQ(std::bit_cast<std::uint64_t>(f.key_double("GAIN")),
            std::bit_cast<std::uint64_t>(1.0 / 3.0));
  EXPECT_EQ(std::bit_cast<std::uint64_t>(f.key_double("TINY")),
            std::bit_cast<std::uint64_t>(1e-300));
  EXPECT_EQ(f.key_long("BIGINT"), 9007199254740993LL);
  EXPECT_EQ(f.key_long("NEG"), -42);
  EXPECT_EQ(f.key_string("OBJECT"), "it's a test");
  EXPECT_EQ(f.key_string("LONGTXT"), long_text);
  EXPECT_EQ(f.key_long("BITPIX"), -64);
  const auto shape = f.image_shape();
  EXPECT_EQ(shape.nx, nx);
  EXPECT_EQ(shape.ny, ny);
  EXPECT_TRUE(bitwise_equal(f.read_image(), pixels));
  std::vector<double> row(nx);
  f.read_image_rows(4, 1, row);
  EXPECT_TRUE(bitwise_equal(row, std::vector<double>(pixels.end() - nx, pixels.end())));
  f.move_to("SECOND");
  EXPECT_EQ(f.image_shape().nx, 3);
  EXPECT_EQ(f.image_shape().ny, 2);
  EXPECT_TRUE(bitwise_equal(f.read_image(), second));
}

TEST_F(FitsFileTmp, TablesFloat32ImagesAndHeaderOnlyPrimary) {
  const std::string path = tmp("table.fits");
  {
    FitsFile f = FitsFile::create(path, false);
    f.write_empty_image();
    f.write_key("SHEAR1", 0.0123, "a key on a header-only primary");
    f.write_table("TRUTH", {{"index", true, {0, 1, 2}}, {"e1", false, {0.1, -0.25, 1.0 / 3.0}}});
    const std::vector<double> pixels = {1.0, 1.0 / 3.0, -2.5, 1e-30, 7.0, 0.0};
    f.write_image(3, 2, pixels, "IMG32", FitsFile::PixelType::kFloat32);
    f.close();
  }
  FitsFile f = FitsFile::open_read(path);
  EXPECT_EQ(f.key_long("NAXIS"), 0);
  EXPECT_EQ(f.key_double("SHEAR1"), 0.0123);
  f.move_to("TRUTH");
  EXPECT_EQ(f.read_column("index"), (std::vector<double>{0, 1, 2}));
  EXPECT_EQ(f.read_column("e1"), (std::vector<double>{0.1, -0.25, 1.0 / 3.0}));  // doubles: bitwise
  EXPECT_EQ(f.key_string("TFORM1"), "K");
  f.move_to("IMG32");
  EXPECT_EQ(f.key_long("BITPIX"), -32);
  const auto img = f.read_image();
  ASSERT_EQ(img.size(), 6u);
  EXPECT_EQ(img[1], static_cast<double>(1.0f / 3.0f));  // rounded to float on writing
  EXPECT_EQ(img[2], -2.5);
  // Columns of different lengths are refused, naming both.
  FitsFile g = FitsFile::create(tmp("bad.fits"), false);
  g.write_empty_image();
  const std::string msg = error_of<FitsError>([&] { g.write_table("T", {{"a", false, {1, 2}}, {"b", false, {1}}}); });
  EXPECT_TRUE(Contains(msg, "column 'b' has 1 rows, column 'a' 2"));
}

TEST_F(FitsFileTmp, Int32ImagesHoldBitMasks) {
  const std::string path = tmp("int32.fits");
  const std::vector<double> bits = {0, 1, 536870912, 1073741824, 3, 0};  // 2^29, 2^30: the MEDS edge bits
  {
    FitsFile f = FitsFile::create(path, false);
    f.write_image(3, 2, bits, "BMASK", FitsFile::PixelType::kInt32);
    f.close();
  }
  FitsFile f = FitsFile::open_read(path);
  EXPECT_EQ(f.key_long("BITPIX"), 32);
  EXPECT_EQ(f.key_string("EXTNAME"), "BMASK");
  EXPECT_EQ(f.read_image(), bits);
}

TEST_F(FitsFileTmp, CreateRespectsOverwrite) {
  const std::string path = tmp("exists.fits");
  const std::vector<double> one = {1.0};
  const std::vector<double> two = {2.0};
  {
    FitsFile f = FitsFile::create(path, false);
    f.write_image(1, 1, one);
  }
  const std::string msg = error_of<FitsError>([&] { FitsFile::create(path, false); });
  EXPECT_TRUE(Contains(msg, "cannot create FITS file '" + path + "'"));
  {
    FitsFile f = FitsFile::create(path, true);
    f.write_image(1, 1, two);
  }
  EXPECT_EQ(FitsFile::open_read(path).read_image(), two);
}

TEST_F(FitsFileTmp, CfitsioWrittenGzipRoundTrip) {
  const std::string path = tmp("written.fits.gz");
  std::vector<double> pixels(40 * 30);
  for (std::size_t i = 0; i < pixels.size(); ++i) pixels[i] = std::exp(-0.01 * i);
  {
    FitsFile f = FitsFile::create(path, true);
    f.write_image(40, 30, pixels, "IMG");
    f.close();  // compression happens here
  }
  std::ifstream in(path, std::ios::binary);
  unsigned char magic[2] = {};
  in.read(reinterpret_cast<char*>(magic), 2);
  EXPECT_EQ(magic[0], 0x1f);  // gzip magic number: the file really is compressed
  EXPECT_EQ(magic[1], 0x8b);
  FitsFile f = FitsFile::open_read(path);
  EXPECT_EQ(f.image_shape().nx, 40);
  EXPECT_TRUE(bitwise_equal(f.read_image(), pixels));
}

TEST_F(FitsFileTmp, TileCompressedFzAutoMovesToImage) {
  // CFITSIO's "[compress ...]" output syntax writes a tile-compressed ".fz" file; "q 0" turns off
  // float quantisation so the round trip is lossless. Its primary HDU is empty, so open_read must
  // find the image in HDU 1 by itself.
  const std::string path = tmp("tiles.fits.fz");
  std::vector<double> pixels(40 * 30);
  for (std::size_t i = 0; i < pixels.size(); ++i) pixels[i] = std::exp(-0.01 * i);
  {
    FitsFile f = FitsFile::create(path + "[compress GZIP; q 0]", true);
    f.write_image(40, 30, pixels, "IMG");
    f.write_key("STAMPSZ", 39, "");
    f.close();
  }
  FitsFile f = FitsFile::open_read(path);
  EXPECT_EQ(f.hdu_count(), 2);
  EXPECT_EQ(f.hdu_index(), 0);
  const auto shape = f.image_shape();
  EXPECT_EQ(shape.nx, 40);
  EXPECT_EQ(shape.ny, 30);
  EXPECT_EQ(f.hdu_index(), 1);
  EXPECT_TRUE(Contains(f.describe(), "tiles.fits.fz[HDU 1 'IMG']"));
  EXPECT_EQ(f.key_long("STAMPSZ"), 39);
  EXPECT_TRUE(bitwise_equal(f.read_image(), pixels));
  std::vector<double> rows(40 * 2);
  f.read_image_rows(28, 2, rows);
  EXPECT_TRUE(bitwise_equal(rows, std::vector<double>(pixels.end() - 80, pixels.end())));
}

TEST_F(FitsFileTmp, MoveTransfersOwnership) {
  FitsFile a = FitsFile::open_read(kCases);
  a.move_to("CASES");
  FitsFile b = std::move(a);
  EXPECT_EQ(b.hdu_index(), 23);
  EXPECT_EQ(b.path(), kCases);
  EXPECT_THROW(a.hdu_index(), FitsError);  // NOLINT(bugprone-use-after-move): tested on purpose
  FitsFile c = FitsFile::open_read(kSet0);
  c = std::move(b);  // closes set_0.fits, takes render_cases.fits
  EXPECT_EQ(c.table_rows(), 22);
  c.close();
  c.close();  // idempotent
  EXPECT_THROW(c.table_rows(), FitsError);
}

// --- listing: header cards, HDU kinds, column names and types ---------------------------------------

TEST_F(FitsFileTmp, HeaderCardsInOrderWithTypesHierarchAndContinue) {
  const std::string path = tmp("cards.fits");
  const std::string long_value = "it's " + std::string(150, 'v') + "&end";  // a '&' inside the value too
  {
    FitsFile f = FitsFile::create(path, false);
    f.write_empty_image();
    f.write_key("NOBJ", 400, "objects");
    f.write_key("GAIN", 0.25, "e/ADU");
    f.write_key("INPUT", long_value, "needs CONTINUE cards");
    f.write_key("TAIL", std::string("a&"), "ends in '&', nothing continues it");
    f.close();
  }
  {  // cards FitsFile does not write: raw, through CFITSIO
    fitsfile* raw = nullptr;
    int status = 0;
    fits_open_file(&raw, path.c_str(), READWRITE, &status);
    for (const char* card : {"HIERARCH metacal_step = 0.01 / sheared images' step", "FLAG    =                    T",
                             "SMALL   =               1.5D-3", "UNDEF   =", "COMMENT flags bit 0 (1): edge",
                             "HISTORY made by a test", "        a blank keyword"}) {
      fits_write_record(raw, card, &status);
    }
    fits_close_file(raw, &status);
    ASSERT_EQ(status, 0);
  }
  FitsFile f = FitsFile::open_read(path);
  const std::vector<FitsFile::HeaderCard> cards = f.header_cards();
  using Type = FitsFile::HeaderCard::Type;
  auto find = [&](const std::string& key) {
    const auto it = std::ranges::find(cards, key, &FitsFile::HeaderCard::key);
    return it == cards.end() ? FitsFile::HeaderCard{"(absent)", Type::kCommentary, "", ""} : *it;
  };
  ASSERT_FALSE(cards.empty());
  EXPECT_EQ(cards.front().key, "SIMPLE");
  EXPECT_EQ(cards.front().type, Type::kLogical);
  EXPECT_EQ(cards.front().value, "T");
  EXPECT_EQ(find("NOBJ").type, Type::kInteger);
  EXPECT_EQ(find("NOBJ").value, "400");
  EXPECT_EQ(find("NOBJ").comment, "objects");
  EXPECT_EQ(find("GAIN").type, Type::kReal);
  EXPECT_EQ(std::stod(find("GAIN").value), 0.25);
  EXPECT_EQ(find("INPUT").type, Type::kString);
  EXPECT_EQ(find("INPUT").value, long_value);  // CONTINUE cards joined, the quote unescaped
  EXPECT_EQ(find("TAIL").value, "a&");
  EXPECT_EQ(find("METACAL_STEP").type, Type::kReal);  // HIERARCH: the long name (CFITSIO upper-cases it)
  EXPECT_EQ(find("METACAL_STEP").value, "0.01");
  EXPECT_EQ(find("METACAL_STEP").comment, "sheared images' step");
  EXPECT_EQ(find("FLAG").type, Type::kLogical);
  EXPECT_EQ(find("SMALL").value, "1.5E-3");  // D exponent as E
  EXPECT_EQ(std::stod(find("SMALL").value), 1.5e-3);
  EXPECT_EQ(find("UNDEF").type, Type::kUndefined);
  const auto comment = std::ranges::find(cards, std::string("flags bit 0 (1): edge"), &FitsFile::HeaderCard::value);
  ASSERT_NE(comment, cards.end());
  EXPECT_EQ(comment->key, "COMMENT");
  EXPECT_EQ(comment->type, Type::kCommentary);
  EXPECT_EQ(find("HISTORY").value, "made by a test");
  EXPECT_EQ(find("").value, "a blank keyword");
  EXPECT_EQ(std::ranges::count(cards, std::string("CONTINUE"), &FitsFile::HeaderCard::key), 0);
  // In card order: the keys written first come first.
  std::vector<std::string> keys;
  for (const auto& c : cards) keys.push_back(c.key);
  const auto at = [&](const std::string& k) { return std::ranges::find(keys, k) - keys.begin(); };
  EXPECT_LT(at("NOBJ"), at("GAIN"));
  EXPECT_LT(at("TAIL"), at("METACAL_STEP"));
  EXPECT_LT(comment - cards.begin(), at("HISTORY"));
}

TEST_F(FitsFileTmp, HduKindsColumnNamesAndIntegerColumns) {
  const std::string path = tmp("kinds.fits");
  {
    FitsFile f = FitsFile::create(path, false);
    f.write_empty_image();
    f.write_table("TRUTH", {{"index", true, {0, 1, 2}}, {"e1", false, {0.1, -0.25, 0.5}}});
    f.write_image(3, 2, std::vector<double>(6, 1.0), "IMG");
    f.close();
  }
  {  // an unsigned (TZERO) integer, a scaled one, a vector, a logical and a string column
    fitsfile* raw = nullptr;
    int status = 0;
    fits_open_file(&raw, path.c_str(), READWRITE, &status);
    char n0[] = "flags", n1[] = "scaled", n2[] = "vec", n3[] = "ok", n4[] = "label";
    char f0[] = "1V", f1[] = "1J", f2[] = "3K", f3[] = "1L", f4[] = "8A";
    char* names[] = {n0, n1, n2, n3, n4};
    char* forms[] = {f0, f1, f2, f3, f4};
    fits_create_tbl(raw, BINARY_TBL, 2, 5, names, forms, nullptr, "MIXED", &status);
    fits_write_key_dbl(raw, "TSCAL2", 0.5, -3, "", &status);
    char l0[] = "1p", l1[] = "noshear ";
    char* labels[] = {l0, l1};
    fits_write_col_str(raw, 5, 1, 1, 2, labels, &status);
    fits_close_file(raw, &status);
    ASSERT_EQ(status, 0);
  }
  FitsFile f = FitsFile::open_read(path);
  ASSERT_EQ(f.hdu_count(), 4);
  EXPECT_EQ(f.hdu_kind(), FitsFile::HduKind::kEmpty);
  f.move_to("TRUTH");
  EXPECT_EQ(f.hdu_kind(), FitsFile::HduKind::kTable);
  EXPECT_EQ(f.column_names(), (std::vector<std::string>{"index", "e1"}));
  EXPECT_TRUE(f.is_integer_column("index"));
  EXPECT_FALSE(f.is_integer_column("E1"));  // names match case-insensitively
  f.move_to("IMG");
  EXPECT_EQ(f.hdu_kind(), FitsFile::HduKind::kImage);
  EXPECT_TRUE(Contains(error_of<FitsError>([&] { f.column_names(); }), "kinds.fits[HDU 2 'IMG']: not a table"));
  f.move_to("MIXED");
  EXPECT_EQ(f.column_names(), (std::vector<std::string>{"flags", "scaled", "vec", "ok", "label"}));
  EXPECT_TRUE(f.is_integer_column("flags"));    // uint32: integers after TZERO
  EXPECT_FALSE(f.is_integer_column("scaled"));  // TSCAL 0.5: reals
  EXPECT_TRUE(f.is_integer_column("vec"));
  EXPECT_TRUE(Contains(error_of<FitsError>([&] { f.is_integer_column("ok"); }),
                       "kinds.fits[HDU 3 'MIXED']: column 'ok' is not numeric"));
  EXPECT_TRUE(Contains(error_of<FitsError>([&] { f.is_integer_column("label"); }), "column 'label' is not numeric"));
  EXPECT_TRUE(Contains(error_of<FitsError>([&] { f.is_integer_column("nope"); }), "[HDU 3 'MIXED']: no column 'nope'"));
  // The character column: one read of its rows, trailing blanks removed, as read_string row by row.
  EXPECT_TRUE(f.is_string_column("LABEL"));
  EXPECT_FALSE(f.is_string_column("flags"));
  std::vector<std::string> labels(2);
  f.read_string_rows("label", 0, labels);
  EXPECT_EQ(labels, (std::vector<std::string>{"1p", "noshear"}));
  EXPECT_EQ(f.read_string("label", 1), "noshear");
  std::vector<std::string> beyond(2);
  EXPECT_TRUE(Contains(error_of<FitsError>([&] { f.read_string_rows("label", 1, beyond); }), "the table has 2 rows"));
  EXPECT_TRUE(Contains(error_of<FitsError>([&] { f.read_string_rows("flags", 0, labels); }),
                       "column 'flags' is not a character column"));
}

TEST_F(FitsFileTmp, ReadColumnsRowsEqualsOneColumnAtATime) {
  const std::string path = tmp("wide.fits");
  constexpr std::size_t kRows = 20000;  // several of CFITSIO's row blocks
  std::vector<double> id(kRows), e1(kRows), snr(kRows);
  for (std::size_t i = 0; i < kRows; ++i) {
    id[i] = static_cast<double>(i) * 3.0 - 7.0;
    e1[i] = std::sin(static_cast<double>(i));
    snr[i] = i % 97 == 0 ? std::nan("") : 1.0 / (1.0 + static_cast<double>(i));
  }
  {
    FitsFile f = FitsFile::create(path, false);
    f.write_empty_image();
    f.write_table("RESULTS", {{"id", true, id}, {"e1", false, e1}, {"snr", false, snr}});
    f.close();
  }
  FitsFile f = FitsFile::open_read(path);
  f.move_to("RESULTS");
  constexpr long long kFirst = 3;
  constexpr std::size_t kCount = kRows - 5;
  std::vector<long long> ids(kCount), want_ids(kCount);
  std::vector<double> e1s(kCount), snrs(kCount), ids_real(kCount), want_e1(kCount), want_snr(kCount);
  const std::vector<FitsFile::ColumnOutput> outputs = {
      {"id", std::span<long long>(ids)}, {"E1", std::span<double>(e1s)}, {"snr", std::span<double>(snrs)},
      {"id", std::span<double>(ids_real)}};
  f.read_columns_rows(kFirst, outputs);
  f.read_column_rows("id", kFirst, std::span<long long>(want_ids));
  f.read_column_rows("e1", kFirst, std::span<double>(want_e1));
  f.read_column_rows("snr", kFirst, std::span<double>(want_snr));
  EXPECT_EQ(ids, want_ids);
  EXPECT_EQ(ids.front(), 2);
  EXPECT_TRUE(bitwise_equal(e1s, want_e1));
  EXPECT_TRUE(bitwise_equal(snrs, want_snr));  // NaNs included
  EXPECT_EQ(ids_real.back(), static_cast<double>(want_ids.back()));
  f.read_columns_rows(0, {});  // nothing asked, nothing read

  std::vector<double> short_out(10);
  std::vector<long long> as_integer(kCount);
  std::string msg = error_of<FitsError>(
      [&] { f.read_columns_rows(0, std::vector<FitsFile::ColumnOutput>{{"e1", std::span<double>(e1s)},
                                                                       {"snr", std::span<double>(short_out)}}); });
  EXPECT_TRUE(Contains(msg, "wide.fits[HDU 1 'RESULTS']: read_columns_rows: the output of column 'snr' holds 10"));
  msg = error_of<FitsError>(
      [&] { f.read_columns_rows(0, std::vector<FitsFile::ColumnOutput>{{"e1", std::span<long long>(as_integer)}}); });
  EXPECT_TRUE(Contains(msg, "column 'e1' is not an integer column"));
  msg = error_of<FitsError>(
      [&] { f.read_columns_rows(0, std::vector<FitsFile::ColumnOutput>{{"e3", std::span<double>(e1s)}}); });
  EXPECT_TRUE(Contains(msg, "[HDU 1 'RESULTS']: no column 'e3'"));
  msg = error_of<FitsError>(
      [&] { f.read_columns_rows(10, std::vector<FitsFile::ColumnOutput>{{"e1", std::span<double>(e1s)}}); });
  EXPECT_TRUE(Contains(msg, "the table has 20000 rows"));
}

// --- errors ----------------------------------------------------------------------------------------

TEST_F(FitsFileTmp, NonExistentFile) {
  const std::string path = tmp("no_such_file.fits");
  const std::string msg = error_of<FitsError>([&] { FitsFile::open_read(path); });
  EXPECT_TRUE(Contains(msg, "cannot open FITS file '" + path + "'"));
}

TEST_F(FitsFileTmp, CorruptFile) {
  const std::string path = tmp("garbage.fits");
  {
    std::ofstream out(path, std::ios::binary);
    for (int i = 0; i < 1000; ++i) out << "this is not a FITS file \x01\x02\xff";
  }
  const std::string msg = error_of<FitsError>([&] { FitsFile::open_read(path); });
  EXPECT_TRUE(Contains(msg, "cannot open FITS file '" + path + "': not a FITS file"));

  const std::string empty = tmp("empty.fits");
  std::ofstream{empty};
  EXPECT_TRUE(Contains(error_of<FitsError>([&] { FitsFile::open_read(empty); }), empty));
}

TEST_F(FitsFileTmp, TruncatedFile) {
  // A valid header whose data stops early: opening may succeed, reading must fail cleanly.
  const std::string path = tmp("truncated.fits");
  {
    std::ifstream in(kSet0, std::ios::binary);
    std::vector<char> head(2880 * 2 + 1000);
    in.read(head.data(), static_cast<std::streamsize>(head.size()));
    std::ofstream out(path, std::ios::binary);
    out.write(head.data(), static_cast<std::streamsize>(head.size()));
  }
  const std::string msg = error_of<FitsError>([&] {
    FitsFile f = FitsFile::open_read(path);
    f.read_image();
  });
  EXPECT_TRUE(Contains(msg, "truncated.fits"));
  const std::string rows_msg = error_of<FitsError>([&] {
    FitsFile f = FitsFile::open_read(path);
    std::vector<double> strip(780 * 10);
    f.read_image_rows(700, 10, strip);
  });
  EXPECT_TRUE(Contains(rows_msg, "truncated.fits"));
}

TEST(FitsFileErrors, MissingKeyword) {
  FitsFile f = FitsFile::open_read(kSet0);
  std::string msg = error_of<FitsError>([&] { f.key_double("NOSUCHKY"); });
  EXPECT_TRUE(Contains(msg, "set_0.fits[HDU 0]: missing header keyword 'NOSUCHKY'"));
  msg = error_of<FitsError>([&] { f.key_long("NOSUCHKY"); });
  EXPECT_TRUE(Contains(msg, "missing header keyword 'NOSUCHKY'"));
  msg = error_of<FitsError>([&] { f.key_string("NOSUCHKY"); });
  EXPECT_TRUE(Contains(msg, "set_0.fits"));
  EXPECT_TRUE(Contains(msg, "'NOSUCHKY'"));
}

TEST(FitsFileErrors, KeywordOfWrongType) {
  FitsFile f = FitsFile::open_read(kSet0);
  std::string msg = error_of<FitsError>([&] { f.key_double("SIZEDEF"); });
  EXPECT_TRUE(Contains(msg, "set_0.fits"));
  EXPECT_TRUE(Contains(msg, "keyword 'SIZEDEF' is not a number"));
  msg = error_of<FitsError>([&] { f.read_key_long("PSFE2"); });
  EXPECT_TRUE(Contains(msg, "keyword 'PSFE2' is not an integer"));
}

// Integer values CFITSIO cannot convert (fuzz_calibration_table found that its converter then
// overflows its own message buffer and aborts): each is a FitsError naming the keyword.
TEST_F(FitsFileTmp, IntegerKeywordsBeyondRangeOrMalformed) {
  const std::string path = tmp("cards.fits");
  {
    FitsFile f = FitsFile::create(path, false);
    f.write_empty_image();
    f.write_key("HUGE", 1LL, "");
    f.write_key("JUNK", 2LL, "");
    f.write_key("PLUS", 3LL, "");
    f.write_key("LOWEST", 4LL, "");
  }
  std::string bytes;
  {
    std::ifstream in(path, std::ios::binary);
    bytes.assign(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
  }
  const auto set_card = [&](const std::string& key, const std::string& value) {
    const std::size_t at = bytes.find(key + std::string(8 - key.size(), ' ') + "= ");
    ASSERT_NE(at, std::string::npos) << key;
    bytes.replace(at, 80, (key + std::string(8 - key.size(), ' ') + "= " + value +
                           std::string(80, ' ')).substr(0, 80));
  };
  set_card("HUGE", "99999999999999999999999999999");
  set_card("JUNK", "12345678901234567890123456789A");
  set_card("PLUS", "              +17");
  set_card("LOWEST", "-9223372036854775808");
  std::ofstream(path, std::ios::binary) << bytes;

  FitsFile f = FitsFile::open_read(path);
  std::string msg = error_of<FitsError>([&] { f.key_long("HUGE"); });
  EXPECT_TRUE(Contains(msg, "cards.fits"));
  EXPECT_TRUE(Contains(msg, "keyword 'HUGE' = 99999999999999999999999999999 is outside the 64-bit"));
  msg = error_of<FitsError>([&] { f.key_long("JUNK"); });
  EXPECT_TRUE(Contains(msg, "keyword 'JUNK' is not"));
  EXPECT_EQ(f.key_long("PLUS"), 17);
  EXPECT_EQ(f.key_long("LOWEST"), std::numeric_limits<long long>::min());
}

TEST(FitsFileErrors, MissingColumn) {
  FitsFile f = FitsFile::open_read(kTruth0);
  f.move_to("TRUTH");
  const std::string msg = error_of<FitsError>([&] { f.read_column("e1_observed"); });
  EXPECT_TRUE(Contains(msg, "truth_0.fits[HDU 1 'TRUTH']: no column 'e1_observed'"));
}

TEST(FitsFileErrors, MoveToUnknownHdu) {
  FitsFile f = FitsFile::open_read(kCases);
  f.move_to("CASE03");
  std::string msg = error_of<FitsError>([&] { f.move_to("CASE99"); });
  EXPECT_TRUE(Contains(msg, "render_cases.fits"));
  EXPECT_TRUE(Contains(msg, "no HDU with EXTNAME 'CASE99'"));
  EXPECT_EQ(f.hdu_index(), 4);  // a failed move leaves the file where it was
  msg = error_of<FitsError>([&] { f.move_to(99); });
  EXPECT_TRUE(Contains(msg, "render_cases.fits"));
  EXPECT_TRUE(Contains(msg, "HDU 99"));
  EXPECT_EQ(f.hdu_index(), 4);
  msg = error_of<FitsError>([&] { f.move_to(-1); });
  EXPECT_TRUE(Contains(msg, "HDU -1"));
}

TEST(FitsFileErrors, ImageFunctionsOnTable) {
  FitsFile f = FitsFile::open_read(kCases);
  f.move_to("CASES");
  std::string msg = error_of<FitsError>([&] { f.image_shape(); });
  EXPECT_TRUE(Contains(msg, "render_cases.fits[HDU 23 'CASES']"));
  EXPECT_TRUE(Contains(msg, "not an image"));
  msg = error_of<FitsError>([&] { f.read_image(); });
  EXPECT_TRUE(Contains(msg, "'CASES'"));
}

TEST(FitsFileErrors, TableFunctionsOnImage) {
  FitsFile f = FitsFile::open_read(kCases);
  f.move_to("CASE01");
  const std::string msg = error_of<FitsError>([&] { f.read_column("hlr"); });
  EXPECT_TRUE(Contains(msg, "render_cases.fits[HDU 2 'CASE01']"));
  EXPECT_TRUE(Contains(msg, "not a table"));
}

TEST(FitsFileErrors, ReadImageRowsOutOfRange) {
  FitsFile f = FitsFile::open_read(kSet0);
  std::vector<double> strip(780 * 20);
  std::string msg = error_of<FitsError>([&] { f.read_image_rows(770, 20, strip); });
  EXPECT_TRUE(Contains(msg, "set_0.fits[HDU 0]"));
  EXPECT_TRUE(Contains(msg, "770"));
  msg = error_of<FitsError>([&] { f.read_image_rows(-1, 20, strip); });
  EXPECT_TRUE(Contains(msg, "set_0.fits"));
  msg = error_of<FitsError>([&] { f.read_image_rows(0, 19, strip); });  // span too large for 19 rows
  EXPECT_TRUE(Contains(msg, "set_0.fits"));
}

TEST_F(FitsFileTmp, WriteErrors) {
  FitsFile read_only = FitsFile::open_read(kSet0);
  const std::vector<double> pixels(4, 1.0);
  std::string msg = error_of<FitsError>([&] { read_only.write_image(2, 2, pixels); });
  EXPECT_TRUE(Contains(msg, "set_0.fits"));
  msg = error_of<FitsError>([&] { read_only.write_key("NEWKEY", 1.0, ""); });
  EXPECT_TRUE(Contains(msg, "'NEWKEY'"));

  FitsFile f = FitsFile::create(tmp("bad.fits"), true);
  msg = error_of<FitsError>([&] { f.write_key("EARLY", 1.0, ""); });  // no header to write into yet
  EXPECT_TRUE(Contains(msg, "bad.fits"));
  EXPECT_TRUE(Contains(msg, "'EARLY'"));
  msg = error_of<FitsError>([&] { f.write_image(3, 2, pixels); });  // 4 pixels for a 3 x 2 image
  EXPECT_TRUE(Contains(msg, "bad.fits"));
  f.write_image(2, 2, pixels);
  msg = error_of<FitsError>([&] { f.write_key("NAN", std::nan(""), ""); });
  EXPECT_TRUE(Contains(msg, "'NAN'"));
}

}  // namespace
}  // namespace stampede::io
