// Tests for the header scan ahead of CFITSIO (io/fits_header_guard), through FitsFile::open_read.
#include "io/fits_header_guard.hpp"

#include <gtest/gtest.h>
#include <zlib.h>

#include <fstream>
#include <iterator>
#include <string>
#include <vector>

#include "io/fits_file.hpp"
#include "support/error_assertions.hpp"
#include "support/header_card_edit.hpp"
#include "support/scratch_dir.hpp"

namespace stampede::io {
namespace {

using stampede::testing::Contains;
using stampede::testing::error_of;

// A catalogue table whose TTYPE2 card is replaced by `card` (padded to 80 bytes), as fuzz_catalogue
// made it.
std::string table_with_card(const stampede::testing::ScratchDir& dir, const std::string& card) {
  const std::string path = dir.path("cat.fits");
  {
    FitsFile f = FitsFile::create(path, true);
    f.write_empty_image();
    f.write_table("CATALOG", {{"id", true, {1, 2}}, {"x", false, {3.0, 4.0}}, {"y", false, {5.0, 6.0}}});
  }
  std::string bytes;
  {
    std::ifstream in(path, std::ios::binary);
    bytes.assign(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
  }
  const std::size_t at = bytes.find("TTYPE2  = ");
  EXPECT_NE(at, std::string::npos);
  bytes.replace(at, 80, (card + std::string(80, ' ')).substr(0, 80));
  std::ofstream(path, std::ios::binary) << bytes;
  return path;
}

using stampede::testing::replace_card;

TEST(FitsHeaderGuard, QuotedColumnNamesOpen) {
  const stampede::testing::ScratchDir dir("stampede_header_guard_");
  FitsFile f = FitsFile::open_read(table_with_card(dir, "TTYPE2  = '" + std::string(68, 'x') + "'"));
  f.move_to(1);
  EXPECT_TRUE(f.has_column(std::string(68, 'x')));
}

// Found by fuzz_catalogue: CFITSIO 4.2.0 copied an unquoted 70-character TTYPEn value into its
// 70-byte column name, and glibc aborted the process ("buffer overflow detected"): `stampede fit
// --catalog` crashed on such a file.
TEST(FitsHeaderGuard, AnUnquotedColumnNameIsAnErrorNotACrash) {
  const stampede::testing::ScratchDir dir("stampede_header_guard_");
  const std::string path = table_with_card(dir, "TTYPE2  = " + std::string(70, 'x'));
  const std::string message = error_of<FitsError>([&] {
    FitsFile f = FitsFile::open_read(path);
    f.move_to(1);
  });
  EXPECT_TRUE(Contains(message, "cat.fits[HDU 1]: header card 'TTYPE2' is not a quoted string")) << message;
}

// Found by the fuzz campaign (F5, all three table readers): CFITSIO also takes "TTYPEn  =" with no
// blank in column 10 as a value, and copied 71 unquoted bytes alike.
TEST(FitsHeaderGuard, AnUnquotedColumnNameWithoutTheValueBlankIsAnErrorNotACrash) {
  const stampede::testing::ScratchDir dir("stampede_header_guard_");
  const std::string path = table_with_card(dir, "TTYPE2  =" + std::string(71, '{'));
  const std::string message = error_of<FitsError>([&] {
    FitsFile f = FitsFile::open_read(path);
    f.move_to(1);
  });
  EXPECT_TRUE(Contains(message, "cat.fits[HDU 1]: header card 'TTYPE2' is not a quoted string")) << message;
  // A quoted name right after the '=' is a name: it opens.
  FitsFile ok = FitsFile::open_read(table_with_card(dir, "TTYPE2  ='x'"));
  ok.move_to(1);
  EXPECT_TRUE(ok.has_column("x"));
}

// Found by the fuzz campaign (F15, fuzz_metadetect_table): an absurd NAXIS2 (2^63 - 1) ended the
// scan of its header, so an unquoted TTYPE after it reached CFITSIO, which overflowed its column
// name and aborted the process. Every card of a header is checked whatever its sizes.
TEST(FitsHeaderGuard, AnUnquotedColumnNameAfterAnAbsurdSizeIsAnErrorNotACrash) {
  const stampede::testing::ScratchDir dir("stampede_header_guard_");
  const std::string path = table_with_card(dir, "TTYPE2  = " + std::string(70, '\x90'));
  replace_card(path, "NAXIS2  = ", "NAXIS2  =    9223372036854775807 number of rows");
  const std::string message = error_of<FitsError>([&] {
    FitsFile f = FitsFile::open_read(path);
    f.move_to(1);
  });
  EXPECT_TRUE(Contains(message, "cat.fits[HDU 1]: header card 'TTYPE2' is not a quoted string")) << message;
}

// Found by the fuzz campaign (F6, fuzz_calibration_table): CFITSIO allocates a column descriptor
// per TFIELDS before reading any, so TFIELDS = 135674990 asked for 22 GB (an out-of-memory kill
// where memory is overcommitted). The standard allows 0..999.
TEST(FitsHeaderGuard, TFieldsBeyondTheStandardsLimitIsAnErrorNotAnAllocation) {
  const stampede::testing::ScratchDir dir("stampede_header_guard_");
  const std::string path = dir.path("cat.fits");
  {
    FitsFile f = FitsFile::create(path, true);
    f.write_empty_image();
    f.write_table("CATALOG", {{"id", true, {1, 2}}, {"x", false, {3.0, 4.0}}});
  }
  replace_card(path, "TFIELDS = ", "TFIELDS =            135674990");
  const std::string message = error_of<FitsError>([&] {
    FitsFile f = FitsFile::open_read(path);
    f.move_to(1);
  });
  EXPECT_TRUE(Contains(message, "cat.fits[HDU 1]: header card 'TFIELDS' = 135674990 is outside the FITS standard's 0..999"))
      << message;
}

// The FitsError of opening a file of `bytes` named `name` in `dir`.
std::string open_error(const stampede::testing::ScratchDir& dir, const std::string& name, const std::string& bytes) {
  const std::string path = dir.path(name);
  std::ofstream(path, std::ios::binary) << bytes;
  return error_of<FitsError>([&] { FitsFile::open_read(path); });
}

// A "gzip" file of `body` bytes after the magic and method bytes `head`, its trailer's ISIZE `isize`.
std::string gzip_claiming(const std::string& head, std::size_t body, char fill, const std::string& isize) {
  return head + std::string(body, fill) + isize;
}

// Found by the fuzz campaign (F7, fuzz_stamp_grid): a 4-byte "gzip" file whose trailer claims
// 3.7 GB uncompressed made CFITSIO allocate that buffer before inflating anything.
TEST(FitsHeaderGuard, AGzipSizeClaimBeyondDeflatesRatioIsAnErrorNotAnAllocation) {
  const stampede::testing::ScratchDir dir("stampede_header_guard_");
  EXPECT_TRUE(Contains(open_error(dir, "tiny.fits.gz", std::string("\x1f\x8b\x0f\xe0", 4)),
                       "tiny.fits.gz: a gzip file of 4 bytes is truncated"));
  // ISIZE = 2^30 from 68 bytes
  EXPECT_TRUE(Contains(open_error(dir, "liar.fits.gz",
                                  gzip_claiming(std::string("\x1f\x8b\x08\x00", 4), 60, '\0',
                                                std::string("\x00\x00\x00\x40", 4))),
                       "liar.fits.gz: gzip trailer claims 1073741824 bytes uncompressed from 68"));
}

// Found by the fuzz campaign (F14, fuzz_psfex): a 125-byte file starting "PK" whose bytes 22-25
// claim 3.3 GB made CFITSIO allocate that much to unzip it; PKZIP files are refused by name.
TEST(FitsHeaderGuard, APkzipFileIsAnErrorNotAnAllocation) {
  const stampede::testing::ScratchDir dir("stampede_header_guard_");
  std::string bytes = "PKL" + std::string(107, '\xc3') + "DEG\x8b";
  EXPECT_TRUE(Contains(open_error(dir, "model.psf", bytes), "model.psf: a PKZIP-compressed file (it starts 'PK') is not read"));
}

// Found by the fuzz campaign (F10, fuzz_calibration_table): "gzip" files whose trailer claims
// less than their own size (0 from 17 KB, 8 KB from 10 KB) made CFITSIO allocate 4 GB more than
// the claim (it takes such a claim for a file that wrapped past 4 GB).
TEST(FitsHeaderGuard, AGzipSizeClaimBelowOneFitsBlockIsAnErrorNotAnAllocation) {
  const stampede::testing::ScratchDir dir("stampede_header_guard_");
  // ISIZE = 0
  EXPECT_TRUE(Contains(open_error(dir, "zero.fits.gz",
                                  gzip_claiming(std::string("\x1f\x8b\x6e\x6e", 4), 17813, 'n', std::string(4, '\0'))),
                       "zero.fits.gz: gzip trailer claims 0 bytes uncompressed from 17821: less than one FITS block"));
  // The same for any claim below the compressed size (8,192 from 10,159: CFITSIO allocated 4 GB + 8 KB).
  EXPECT_TRUE(Contains(open_error(dir, "small.fits.gz",
                                  gzip_claiming(std::string("\x1f\x8b\x22\x00", 4), 10151, 'n',
                                                std::string("\x00\x20\x00\x00", 4))),
                       "small.fits.gz: gzip trailer claims 8192 bytes uncompressed from 10159: less than the compressed size"));
}

// Found by the fuzz campaign (F8, fuzz_psf_image; undefined behaviour under UBSan): a BITPIX of
// 2^60 - 1 overflowed the scan's size of the data. Now the scan leaves a non-standard BITPIX to
// CFITSIO, which refuses it: an error naming the file.
TEST(FitsHeaderGuard, ANonStandardBitpixIsAnErrorWithoutOverflow) {
  const stampede::testing::ScratchDir dir("stampede_header_guard_");
  const std::string path = dir.path("img.fits");
  {
    FitsFile f = FitsFile::create(path, true);
    f.write_image(4, 4, std::vector<double>(16, 1.0));
  }
  std::string bytes;
  {
    std::ifstream in(path, std::ios::binary);
    bytes.assign(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
  }
  const std::size_t at = bytes.find("BITPIX  = ");
  ASSERT_NE(at, std::string::npos);
  bytes.replace(at, 80, ("BITPIX  =  1152921504606846975" + std::string(80, ' ')).substr(0, 80));
  std::ofstream(path, std::ios::binary) << bytes;
  EXPECT_TRUE(Contains(error_of<FitsError>([&] {
                         FitsFile f = FitsFile::open_read(path);
                         f.read_image();
                       }),
                       "img.fits"));
}

// The same card in a gzip-compressed file: CFITSIO inflates it in memory and crashed alike (the
// fuzz campaign's open finding); the scan reads it through zlib first.
TEST(FitsHeaderGuard, AnUnquotedColumnNameInAGzipFileIsAnErrorNotACrash) {
  const stampede::testing::ScratchDir dir("stampede_header_guard_");
  const std::string path = table_with_card(dir, "TTYPE2  = " + std::string(70, 'x'));
  std::string bytes;
  {
    std::ifstream in(path, std::ios::binary);
    bytes.assign(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
  }
  const std::string gz = dir.path("cat.fits.gz");
  gzFile out = gzopen(gz.c_str(), "wb");
  ASSERT_NE(out, nullptr);
  ASSERT_EQ(gzwrite(out, bytes.data(), static_cast<unsigned>(bytes.size())), static_cast<int>(bytes.size()));
  gzclose(out);
  const std::string message = error_of<FitsError>([&] {
    FitsFile f = FitsFile::open_read(gz);
    f.move_to(1);
  });
  EXPECT_TRUE(Contains(message, "cat.fits.gz[HDU 1]: header card 'TTYPE2' is not a quoted string")) << message;
  // A valid compressed table still opens.
  const std::string good = table_with_card(dir, "TTYPE2  = 'x'");
  bytes.clear();
  {
    std::ifstream in(good, std::ios::binary);
    bytes.assign(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
  }
  const std::string good_gz = dir.path("good.fits.gz");
  out = gzopen(good_gz.c_str(), "wb");
  ASSERT_NE(out, nullptr);
  gzwrite(out, bytes.data(), static_cast<unsigned>(bytes.size()));
  gzclose(out);
  FitsFile f = FitsFile::open_read(good_gz);
  f.move_to(1);
  EXPECT_TRUE(f.has_column("x"));
}

// A 4 x 4 image file's bytes, with `edit` applied to them.
template <class Edit>
std::string image_file(const stampede::testing::ScratchDir& dir, Edit edit) {
  const std::string path = dir.path("source.fits");
  {
    FitsFile f = FitsFile::create(path, true);
    f.write_image(4, 4, std::vector<double>(16, 1.0));
  }
  std::ifstream in(path, std::ios::binary);
  std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  edit(bytes);
  return bytes;
}

// Found by the fuzz campaign (F11, fuzz_stamp_grid; out of memory): a 2,957-byte file whose
// header claims 2,107,483,648 x 3 pixels passed every check, and the grid reader sized its row
// buffers (gigabytes) from the header before reading a pixel.
TEST(FitsHeaderGuard, DataThatCannotFitInTheFileIsAnErrorNotAnAllocation) {
  const stampede::testing::ScratchDir dir("stampede_header_guard_");
  const std::string huge = image_file(dir, [](std::string& b) {
    const std::size_t at = b.find("NAXIS1  = ");
    b.replace(at, 80, ("NAXIS1  =           2107483648" + std::string(80, ' ')).substr(0, 80));
  });
  EXPECT_TRUE(Contains(open_error(dir, "huge.fits", huge),
                       "huge.fits[HDU 0]: header says 67439476736 bytes of data but the file ends 2880 bytes after the header"));
  // The finding's header wrote its numbers with a sign ("+32"), which the scan must read too.
  const std::string signed_huge = image_file(dir, [](std::string& b) {
    const std::size_t at = b.find("NAXIS1  = ");
    b.replace(at, 80, ("NAXIS1  =          +2107483648" + std::string(80, ' ')).substr(0, 80));
  });
  EXPECT_TRUE(Contains(open_error(dir, "signed.fits", signed_huge), "signed.fits[HDU 0]: header says 67439476736 bytes"));
  // A file cut inside its data is refused alike, before any read.
  EXPECT_TRUE(Contains(open_error(dir, "cut.fits", image_file(dir, [](std::string& b) { b.resize(2880 + 40); })),
                       "cut.fits[HDU 0]: header says 128 bytes of data but the file ends 40 bytes after the header"));
  // The same in a gzip file: the trailer's size is what CFITSIO parses.
  const std::string gz = dir.path("huge.fits.gz");
  gzFile out = gzopen(gz.c_str(), "wb");
  ASSERT_NE(out, nullptr);
  gzwrite(out, huge.data(), static_cast<unsigned>(huge.size()));
  gzclose(out);
  EXPECT_TRUE(Contains(error_of<FitsError>([&] { FitsFile::open_read(gz); }),
                       "huge.fits.gz[HDU 0]: header says 67439476736 bytes"));
  // The intact file opens and reads.
  const std::string intact = dir.path("intact.fits");
  std::ofstream(intact, std::ios::binary) << image_file(dir, [](std::string&) {});
  FitsFile f = FitsFile::open_read(intact);
  EXPECT_EQ(f.read_image().size(), 16u);
}

// Found by the fuzz campaign (F12, fuzz_stamp_grid; out of memory): CFITSIO read NAXIS1 =
// 854,775,807 from a card whose value indicator is not in column 9 (which the header scan, keeping
// to the standard, skips), and the grid reader sized a 6.8 GB row buffer from it. The size CFITSIO
// parsed is checked against the file when a reader asks for it.
TEST(FitsHeaderGuard, DataCfitsioParsedBeyondTheFileIsAnErrorNotAnAllocation) {
  const stampede::testing::ScratchDir dir("stampede_header_guard_");
  const std::string path = dir.path("odd.fits");
  std::ofstream(path, std::ios::binary) << image_file(dir, [](std::string& b) {
    const std::size_t at = b.find("NAXIS1  = ");
    b.replace(at, 80, ("NAXIS1  SEEDBITPIX  = 854775807/ length of data axis 1" + std::string(80, ' ')).substr(0, 80));
  });
  const std::string message = error_of<FitsError>([&] {
    FitsFile f = FitsFile::open_read(path);
    f.image_shape();
  });
  EXPECT_TRUE(Contains(message, "odd.fits[HDU 0]: header says 27352825824 bytes of data")) << message;  // 854775807 x 4 x 8
  EXPECT_TRUE(Contains(message, "truncated, or the header's sizes are wrong")) << message;
}

// Found by the fuzz campaign (F13, fuzz_catalogue; out of memory): a TFIELDS card whose value
// indicator sits past garbage ("TFIELDS \xbd ... 27 SIMPLE  = 0...036155707"), which CFITSIO reads
// as 36,155,707 fields and allocates 5.8 GB of column descriptors for while moving to the HDU. The
// scan reads such cards as CFITSIO does.
TEST(FitsHeaderGuard, AFreeFormatTfieldsBeyondTheStandardsLimitIsAnErrorNotAnAllocation) {
  const stampede::testing::ScratchDir dir("stampede_header_guard_");
  const std::string path =
      table_with_card(dir, "TTYPE2  = 'x'");  // a valid table, whose TFIELDS card is then replaced
  std::string bytes;
  {
    std::ifstream in(path, std::ios::binary);
    bytes.assign(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
  }
  const std::size_t at = bytes.find("TFIELDS = ");
  ASSERT_NE(at, std::string::npos);
  bytes.replace(at, 80, (std::string("TFIELDS \xbd                   3 SIMPLE  =          000000000000000000000036155707") +
                         std::string(80, ' ')).substr(0, 80));
  const std::string message = open_error(dir, "fields.fits", bytes);
  EXPECT_TRUE(Contains(message, "fields.fits[HDU 1]: header card 'TFIELDS' = 36155707 is outside the FITS standard's 0..999"))
      << message;
}

}  // namespace
}  // namespace stampede::io
