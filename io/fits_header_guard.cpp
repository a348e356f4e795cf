// The header scan ahead of CFITSIO; see fits_header_guard.hpp.
#include "io/fits_header_guard.hpp"

#include <zlib.h>

#include <algorithm>
#include <charconv>
#include <fstream>
#include <memory>
#include <optional>
#include <string_view>

#include "io/fits_error.hpp"

namespace stampede::io {
namespace {

constexpr long long kBlock = 2880, kCard = 80;

// The value text of a card as CFITSIO reads it: after "= " in columns 9-10, or, where column 9
// is not '=', after the first '=' further on (CFITSIO reads such free-format cards: fuzz findings
// F12, "NAXIS1  SEEDBITPIX  = 854775807", and F13, a TFIELDS of 36,155,707 behind garbage).
std::optional<std::string_view> card_value(std::string_view card) {
  const std::size_t eq = card.find('=', 8);
  if (eq == std::string_view::npos) return std::nullopt;
  return card.substr(eq + 1);
}

// The integer value of a card, if it is one.
std::optional<long long> card_integer(std::string_view card) {
  const auto value = card_value(card);
  if (!value) return std::nullopt;
  std::string_view v = *value;
  v.remove_prefix(std::min(v.find_first_not_of(' '), v.size()));
  if (v.starts_with('+')) v.remove_prefix(1);  // "+32" is a FITS integer; from_chars refuses the sign
  long long n = 0;
  const auto [end, ec] = std::from_chars(v.data(), v.data() + v.size(), n);
  if (ec != std::errc() || end == v.data()) return std::nullopt;
  return n;
}

// The file's bytes as CFITSIO will parse them: a gzip-compressed file (which CFITSIO inflates
// in memory before parsing, so the same card crashes it there) through zlib, forward seeks only.
class ByteSource {
 public:
  explicit ByteSource(const std::string& path) {
    std::ifstream probe(path, std::ios::binary);
    unsigned char magic[2] = {0, 0};
    probe.read(reinterpret_cast<char*>(magic), 2);
    if (probe && magic[0] == 0x1f && magic[1] == 0x8b) {
      gz_.reset(gzopen(path.c_str(), "rb"));
    } else {
      plain_.open(path, std::ios::binary);
    }
  }
  bool good() const { return gz_ ? true : static_cast<bool>(plain_); }
  bool seek(long long offset) {
    if (gz_) return gzseek(gz_.get(), static_cast<z_off_t>(offset), SEEK_SET) == offset;
    plain_.seekg(offset);
    return static_cast<bool>(plain_);
  }
  bool read(char* out, long long n) {
    if (gz_) return gzread(gz_.get(), out, static_cast<unsigned>(n)) == n;
    return static_cast<bool>(plain_.read(out, n));
  }

 private:
  struct GzClose {
    void operator()(gzFile f) const { gzclose(f); }
  };
  std::unique_ptr<gzFile_s, GzClose> gz_;
  std::ifstream plain_;
};

}  // namespace

// CFITSIO inflates a gzip file in memory into a buffer of the size its trailer claims (ISIZE, the
// last 4 bytes): a 4-byte file claiming 3.7 GB got that buffer (fuzz finding F7). Deflate cannot
// expand more than 1032:1, so a claim beyond that (plus one FITS block) is not a gzip file's.
// Returns the bytes CFITSIO will parse: the file's size, the gzip claim, or -1 where a gzip file
// may have wrapped past 4 GB (its claim is then the size mod 2^32) or the file cannot be read.
long long parsed_size(const std::string& root) {
  std::ifstream f(root, std::ios::binary | std::ios::ate);
  if (!f) return -1;
  const long long size = static_cast<long long>(f.tellg());
  unsigned char head[2] = {0, 0};
  f.seekg(0);
  f.read(reinterpret_cast<char*>(head), 2);
  // CFITSIO inflates a file starting "PK" as PKZIP into a buffer of the size its local header
  // claims (bytes 22-25), unchecked (fuzz finding F14: 3.3 GB from 125 bytes), and the scan below
  // cannot see inside a zip archive: such files are refused. Survey files are plain, gzip or fpack.
  if (f && head[0] == 'P' && head[1] == 'K')
    throw FitsError(root + ": a PKZIP-compressed file (it starts 'PK') is not read; give it as FITS, gzip (.gz) or "
                           "tile-compressed (.fz)");
  if (!f || head[0] != 0x1f || head[1] != 0x8b) return size;
  if (size < 18) throw FitsError(root + ": a gzip file of " + std::to_string(size) + " bytes is truncated (a gzip member has 18 at least)");
  unsigned char tail[4];
  f.seekg(size - 4);
  f.read(reinterpret_cast<char*>(tail), 4);
  const long long claimed = tail[0] | (tail[1] << 8) | (tail[2] << 16) | (static_cast<long long>(tail[3]) << 24);
  if (claimed > 1032 * size + kBlock)
    throw FitsError(root + ": gzip trailer claims " + std::to_string(claimed) + " bytes uncompressed from " +
                    std::to_string(size) + ": more than deflate can expand; not a valid gzip file");
  // CFITSIO takes a claim below the compressed size for a file that wrapped past 4 GB (ISIZE is
  // the size mod 2^32) and allocates 4 GB more (fuzz finding F10: claims of 0 and 8,192 bytes from
  // 17,821 and 10,159). A file too small to inflate to 4 GB cannot have wrapped, and a FITS file
  // has one 2880-byte block at least.
  if ((claimed < size || claimed < kBlock) && 1032 * size + kBlock < (1LL << 32))
    throw FitsError(root + ": gzip trailer claims " + std::to_string(claimed) + " bytes uncompressed from " +
                    std::to_string(size) + ": less than " + (claimed < kBlock ? "one FITS block" : "the compressed size") +
                    "; not a gzip-compressed FITS file");
  return 1032 * size + kBlock < (1LL << 32) ? claimed : -1;
}

void check_fits_headers(const std::string& root) {
  const long long file_bytes = parsed_size(root);
  ByteSource in(root);
  char card_bytes[kCard];
  long long hdu_start = 0;
  for (int hdu = 0; hdu < 1000 && in.good(); ++hdu) {
    long long bitpix = 0, naxis = 0, pcount = 0, gcount = 1, pixels = 1;
    bool end = false, absurd = false;
    long long cards = 0;
    if (!in.seek(hdu_start)) return;
    while (!end && in.read(card_bytes, kCard)) {
      const std::string_view card(card_bytes, kCard);
      if (hdu == 0 && cards == 0 && !card.starts_with("SIMPLE  =")) return;  // not plain FITS: CFITSIO's to judge
      ++cards;
      const std::string_view key = card.substr(0, 8);
      if (key.starts_with("END ") && key.find_first_not_of(' ', 3) == std::string_view::npos) {
        end = true;
        break;
      }
      // CFITSIO takes an '=' in column 9 as a value indicator even without the standard's blank
      // in column 10 (fuzz finding F5): the column-name check must too.
      if (key.starts_with("TTYPE") && card_value(card)) {
        const std::string_view v = *card_value(card);
        const std::size_t first = v.find_first_not_of(' ');
        if (first != std::string_view::npos && v[first] != '\'')
          throw FitsError(root + "[HDU " + std::to_string(hdu) + "]: header card '" + std::string(key.substr(0, key.find(' '))) +
                          "' is not a quoted string (a column name must be one)");
        continue;
      }
      const auto value = card_integer(card);
      if (key == "BITPIX  " && value) {
        bitpix = *value;
      } else if (key == "NAXIS   " && value) {
        naxis = *value;
      } else if (key.starts_with("NAXIS") && value && *value >= 0) {
        // Absurd sizes are CFITSIO's to report, once every card of the header has been checked
        // (fuzz finding F15: NAXIS2 = 2^63 - 1 ended the scan before an unquoted TTYPE10).
        if (*value != 0 && pixels > (1LL << 50) / *value) absurd = true;
        if (!absurd) pixels *= *value;
      } else if (key == "PCOUNT  " && value) {
        pcount = *value;
      } else if (key == "TFIELDS " && value && (*value < 0 || *value > 999)) {
        // CFITSIO allocates a column descriptor per field before reading any: 135,674,990 of them
        // asked for 22 GB (fuzz finding F6). The standard's limit is 999.
        throw FitsError(root + "[HDU " + std::to_string(hdu) + "]: header card 'TFIELDS' = " + std::to_string(*value) +
                        " is outside the FITS standard's 0..999");
      } else if (key == "GCOUNT  " && value) {
        gcount = *value;
      }
    }
    if (!end || absurd) return;
    const long long header = (cards + kBlock / kCard - 1) / (kBlock / kCard) * kBlock;
    // Only the standard's BITPIX values: any other (fuzz finding F8: 2^60 - 1) overflowed the size
    // below. Such a header, and absurd counts, are CFITSIO's to report.
    if (bitpix != 8 && bitpix != 16 && bitpix != 32 && bitpix != 64 && bitpix != -32 && bitpix != -64) return;
    const long long bytes_per = (bitpix < 0 ? -bitpix : bitpix) / 8;
    if (pcount < 0 || gcount < 0 || pcount > (1LL << 50) || gcount > 256) return;  // no 64-bit overflow below
    const long long data = naxis == 0 ? 0 : bytes_per * gcount * (pcount + pixels);
    if (data > (1LL << 52)) return;  // 4 PB: not a file; and 1000 HDUs of less cannot overflow hdu_start
    // A header whose data cannot be in the file: readers size their buffers from the header
    // before reading a pixel (fuzz finding F11: 2.1e9 x 3 pixels claimed in 2,957 bytes). The
    // last block's padding may be missing; the data itself may not.
    if (file_bytes >= 0 && hdu_start + header + data > file_bytes)
      throw FitsError(root + "[HDU " + std::to_string(hdu) + "]: header says " + std::to_string(data) +
                      " bytes of data but the file ends " + std::to_string(std::max(0LL, file_bytes - hdu_start - header)) +
                      " bytes after the header: truncated, or the header's sizes are wrong");
    hdu_start += header + (data + kBlock - 1) / kBlock * kBlock;
  }
}

}  // namespace stampede::io
