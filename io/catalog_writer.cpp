// CatalogWriter implementation: column table, FITS header, commits and crash repair (see
// catalog_writer.hpp for the protocol).
//
// CFITSIO is used directly: FitsFile has no table writing and hides its fitsfile*. Files are opened
// with fits_create_diskfile / fits_open_diskfile so that paths are taken literally (no extended
// syntax). Raw POSIX calls do what CFITSIO cannot: fsync, truncation, atomic rename.
#include "io/catalog_writer.hpp"

#include <fcntl.h>
#include <fitsio.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <bit>
#include <cctype>
#include <cerrno>
#include <charconv>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string_view>
#include <system_error>

namespace stampede::io {
namespace {

// ---- the columns --------------------------------------------------------------------------------

enum class ColType { kI64, kI32, kU32, kF64 };

// One column of both outputs: the FITS table and the text file are written from this one list, so
// they cannot disagree. Integer columns read through `integer` (widened; every source type fits
// its FITS type exactly), double columns through `real`.
struct Column {
  const char* name;
  ColType type;
  const char* unit;         // TUNITn; "" = dimensionless or data units
  const char* description;  // TCOMMn, at most 68 characters (one FITS string card)
  std::int64_t (*integer)(const ObjectRecord&);
  double (*real)(const ObjectRecord&);
};

using R = const ObjectRecord&;
constexpr double param(R r, Param p) { return r.fit.params[index(p)]; }

constexpr Column real(const char* name, const char* unit, const char* description,
                      double (*get)(R)) {
  return {name, ColType::kF64, unit, description, nullptr, get};
}
constexpr Column integer(const char* name, ColType type, const char* description,
                         std::int64_t (*get)(R)) {
  return {name, type, "", description, get, nullptr};
}

const Column kGridPositions[] = {
    integer("id", ColType::kI64, "object id: iy * nx + ix",
            [](R r) -> std::int64_t { return r.id; }),
    integer("ix", ColType::kI32, "stamp column in the grid, 0-based",
            [](R r) -> std::int64_t { return r.ix; }),
    integer("iy", ColType::kI32, "stamp row in the grid, 0-based",
            [](R r) -> std::int64_t { return r.iy; }),
};
const Column kCataloguePositions[] = {
    integer("id", ColType::kI64, "object id from the input catalogue",
            [](R r) -> std::int64_t { return r.id; }),
    real("x_image", "pixel", "catalogue x position, FITS 1-based image pixels",
         [](R r) { return r.x_image; }),
    real("y_image", "pixel", "catalogue y position, FITS 1-based image pixels",
         [](R r) { return r.y_image; }),
};
const Column kFitColumns[] = {
    real("x0", "pixel", "fitted centroid x, 0-based pixels within the stamp",
         [](R r) { return param(r, Param::kX0); }),
    real("y0", "pixel", "fitted centroid y, 0-based pixels within the stamp",
         [](R r) { return param(r, Param::kY0); }),
    real("e1", "", "ellipticity (a-b)/(a+b) along x, after the mirror",
         [](R r) { return param(r, Param::kE1); }),
    real("e2", "", "ellipticity along y = x, after the mirror",
         [](R r) { return param(r, Param::kE2); }),
    real("radius", "pixel", "disc half-light radius sqrt(ab), after softening",
         [](R r) { return param(r, Param::kRadius); }),
    real("bulge_A", "", "bulge central intensity, data units per pixel^2",
         [](R r) { return param(r, Param::kBulgeA); }),
    real("disc_A", "", "disc central intensity, data units per pixel^2",
         [](R r) { return param(r, Param::kDiscA); }),
    real("bulge_flux", "", "bulge flux, data units", [](R r) { return r.fit.bulge_flux; }),
    real("disc_flux", "", "disc flux, data units", [](R r) { return r.fit.disc_flux; }),
    real("flux", "", "total flux, data units", [](R r) { return r.fit.flux; }),
    real("e1_err", "", "error of e1 from (J^T W J)^-1", [](R r) { return r.fit.e1_err; }),
    real("e2_err", "", "error of e2 from (J^T W J)^-1", [](R r) { return r.fit.e2_err; }),
    real("snr", "", "S/N sqrt(sum w m^2) of the best model", [](R r) { return r.fit.snr; }),
    real("chi2", "", "sum w (d - m)^2 over used pixels", [](R r) { return r.fit.chi2; }),
    real("likelihood", "", "-chi2 / 2", [](R r) { return r.fit.likelihood; }),
    integer("n_iter", ColType::kI32, "solver iterations (Jacobian evaluations)",
            [](R r) -> std::int64_t { return r.fit.iterations; }),
    integer("n_eval", ColType::kI32, "model evaluations",
            [](R r) -> std::int64_t { return r.fit.evaluations; }),
    integer("stop_reason", ColType::kI32, "StopReason: the rule that stopped the solver",
            [](R r) -> std::int64_t { return static_cast<int>(r.fit.stop_reason); }),
    integer("status", ColType::kI32, "FitStatus, named by header keys STATUSn",
            [](R r) -> std::int64_t { return static_cast<int>(r.fit.status); }),
    integer("flags", ColType::kU32, "fit and input flag bits, see COMMENT cards",
            [](R r) -> std::int64_t { return r.flags; }),
    real("time_us", "us", "wall time of the fit", [](R r) { return r.time_us; }),
    real("psf_e1", "", "PSF ellipticity e1", [](R r) { return r.psf_e1; }),
    real("psf_e2", "", "PSF ellipticity e2", [](R r) { return r.psf_e2; }),
    real("psf_fwhm", "pixel", "PSF FWHM", [](R r) { return r.psf_fwhm; }),
};

std::vector<Column> columns_for(PositionColumns positions) {
  std::vector<Column> out;
  if (positions == PositionColumns::kGrid) {
    out.assign(std::begin(kGridPositions), std::end(kGridPositions));
  } else {
    out.assign(std::begin(kCataloguePositions), std::end(kCataloguePositions));
  }
  out.insert(out.end(), std::begin(kFitColumns), std::end(kFitColumns));
  return out;
}

const char* tform(ColType t) {
  switch (t) {
    case ColType::kI64: return "1K";
    case ColType::kI32: return "1J";
    case ColType::kU32: return "1V";  // CFITSIO: stored as J with TZERO = 2147483648
    case ColType::kF64: return "1D";
  }
  return "?";
}

long row_bytes(const std::vector<Column>& columns) {
  long n = 0;
  for (const Column& c : columns) n += (c.type == ColType::kI64 || c.type == ColType::kF64) ? 8 : 4;
  return n;
}

// Flag bits documented in the header; the asserts keep the text tied to the enums.
struct FlagDoc {
  std::uint32_t bit;
  const char* text;
};
static_assert(kFlagMaskedPixels == 1u << 0 && kFlagDefaultStart == 1u << 1 &&
              kFlagAtBound == 1u << 2 && kFlagMirrored == 1u << 3 && kFlagNoErrors == 1u << 4 &&
              kFlagNotConverged == 1u << 5 && kFlagUnweighted == 1u << 6 &&
              kFlagEdge == 1u << 16 && kFlagPsfFailure == 1u << 17,
              "flag bits changed: update kFlagDocs");
const FlagDoc kFlagDocs[] = {
    {kFlagMaskedPixels, "some pixels had zero weight"},
    {kFlagDefaultStart, "moments failed; started from default values"},
    {kFlagAtBound, "a free parameter ended at a bound"},
    {kFlagMirrored, "|e| ended beyond the mirror radius; e folded"},
    {kFlagNoErrors, "J^T W J singular at the optimum; errors NaN"},
    {kFlagNotConverged, "max iterations reached"},
    {kFlagUnweighted, "unweighted fit; chi2, errors, snr in data units"},
    {kFlagEdge, "stamp reaches beyond the image; outside masked"},
    {kFlagPsfFailure, "the object's PSF could not be built"},
};
constexpr int kNumStatuses = 7;  // FitStatus::kOk .. kPsfFailure
static_assert(static_cast<int>(FitStatus::kPsfFailure) == kNumStatuses - 1,
              "FitStatus changed: update kNumStatuses");

// Rows per fits_write_col call. A chunk spans at most 256 * 200 bytes = 50 KiB of table, inside
// CFITSIO's 40 x 2880-byte buffer pool, so writing it column by column touches each buffer from
// memory; a whole large batch per column would evict and re-read blocks once per column.
constexpr std::size_t kChunkRows = 256;

constexpr std::string_view kCheckpointMagic = "stampede catalogue checkpoint 1";

// ---- error text and POSIX helpers ---------------------------------------------------------------

std::string errno_text(int e) { return std::generic_category().message(e); }

// CFITSIO's text for `status`; also empties its global message stack so stale messages do not
// pile up.
std::string fits_text(int status) {
  char text[FLEN_STATUS] = {};
  fits_get_errstatus(status, text);
  fits_clear_errmsg();
  return std::string(text) + " (CFITSIO status " + std::to_string(status) + ")";
}

[[noreturn]] void fail(const std::string& what) { throw CatalogError(what); }
[[noreturn]] void fail_errno(const std::string& what) { fail(what + ": " + errno_text(errno)); }

void write_all(int fd, std::string_view bytes, const std::string& path) {
  while (!bytes.empty()) {
    const ssize_t n = ::write(fd, bytes.data(), bytes.size());
    if (n < 0) {
      if (errno == EINTR) continue;
      fail_errno("cannot write '" + path + "'");
    }
    bytes.remove_prefix(static_cast<std::size_t>(n));
  }
}

void fsync_or_throw(int fd, const std::string& path) {
  if (::fsync(fd) != 0) fail_errno("cannot sync '" + path + "' to disk");
}

std::string directory_of(const std::string& path) {
  const std::string dir = std::filesystem::path(path).parent_path().string();
  return dir.empty() ? "." : dir;
}

// Makes renames and creations in the directory durable. Filesystems that cannot sync a directory
// (EINVAL) order metadata themselves.
void fsync_directory(const std::string& file_in_dir) {
  const std::string dir = directory_of(file_in_dir);
  const int fd = ::open(dir.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC);
  if (fd < 0) fail_errno("cannot open directory '" + dir + "'");
  const int rc = ::fsync(fd);
  const int e = errno;
  ::close(fd);
  if (rc != 0 && e != EINVAL) fail("cannot sync directory '" + dir + "': " + errno_text(e));
}

void remove_if_present(const std::string& path) {
  if (::unlink(path.c_str()) != 0 && errno != ENOENT) fail_errno("cannot remove '" + path + "'");
}

bool exists(const std::string& path) {
  struct stat st {};
  return ::stat(path.c_str(), &st) == 0;
}

long long file_size(int fd, const std::string& path) {
  struct stat st {};
  if (::fstat(fd, &st) != 0) fail_errno("cannot stat '" + path + "'");
  return static_cast<long long>(st.st_size);
}

// ---- header keys --------------------------------------------------------------------------------

std::string upper(std::string s) {
  for (char& c : s) c = static_cast<char>(std::toupper(static_cast<unsigned char>(c)));
  return s;
}

bool is_standard_key(const std::string& key) {
  return !key.empty() && key.size() <= 8 && std::ranges::all_of(key, [](char c) {
    return (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') || c == '_' || c == '-';
  });
}

// Keys the table's structure or this writer owns; a configuration value must not replace them.
bool is_reserved(const std::string& key) {
  static const char* const kExact[] = {"SIMPLE", "XTENSION", "BITPIX", "NAXIS", "PCOUNT", "GCOUNT",
                                       "TFIELDS", "EXTNAME", "EXTVER", "EXTLEVEL", "THEAP", "END",
                                       "CONTINUE", "COMMENT", "HISTORY", "LONGSTRN", "HIERARCH"};
  static const char* const kIndexed[] = {"NAXIS", "TTYPE", "TFORM", "TUNIT", "TZERO", "TSCAL",
                                         "TNULL", "TCOMM", "TDIM", "TDISP", "STATUS"};
  for (const char* k : kExact) {
    if (key == k) return true;
  }
  for (std::string_view prefix : kIndexed) {
    if (key.size() > prefix.size() && key.starts_with(prefix) &&
        std::all_of(key.begin() + static_cast<std::ptrdiff_t>(prefix.size()), key.end(),
                    [](char c) { return c >= '0' && c <= '9'; })) {
      return true;
    }
  }
  return false;
}

bool printable(std::string_view s) {
  return std::ranges::all_of(s, [](char c) { return c >= 0x20 && c <= 0x7e; });
}

// Validates the header list, upper-cases the keys and keeps the last value of a repeated key (at
// the position of its first appearance).
std::vector<std::pair<std::string, std::string>> normalise_header(
    const std::vector<std::pair<std::string, std::string>>& header) {
  std::vector<std::pair<std::string, std::string>> out;
  for (const auto& [raw_key, value] : header) {
    const std::string key = upper(raw_key);
    if (key.empty() || key.front() == ' ' || key.back() == ' ' || !printable(key) ||
        key.find('=') != std::string::npos || key.find('\'') != std::string::npos) {
      fail("header key '" + raw_key +
           "' is not a valid FITS keyword (printable ASCII, no '=', quote or edge spaces)");
    }
    if (is_standard_key(key) ? is_reserved(key) : key.starts_with("HIERARCH")) {
      fail("header key '" + raw_key + "' is reserved for the table structure");
    }
    if (!printable(value)) {
      fail("value of header key '" + raw_key + "' has characters a FITS header cannot hold " +
           "(printable ASCII only)");
    }
    // "HIERARCH KEY = '" plus one escaped quote and "&'" must fit one 80-character card.
    if (!is_standard_key(key) && key.size() > 80 - 17) {
      fail("header key '" + raw_key + "' is too long for a FITS card");
    }
    auto same = std::ranges::find_if(out, [&](const auto& kv) { return kv.first == key; });
    if (same != out.end()) {
      same->second = value;
    } else {
      out.emplace_back(key, value);
    }
  }
  return out;
}

// Cards for a HIERARCH string key. Built by hand because CFITSIO 4.2's fits_update_key_longstr
// drops the '&' continuation marker when a long HIERARCH name leaves little room on the first
// card, so readers would lose the rest of the value. Quotes are doubled and never split.
std::vector<std::string> hierarch_cards(const std::string& key, const std::string& value) {
  std::vector<std::string> cards;
  std::string card = "HIERARCH " + key + " = '";
  std::size_t pos = 0;
  auto escaped = [](char c) { return c == '\'' ? std::string("''") : std::string(1, c); };
  for (;;) {
    std::string rest;
    for (std::size_t i = pos; i < value.size(); ++i) rest += escaped(value[i]);
    if (card.size() + rest.size() + 1 <= 80) {
      cards.push_back(card + rest + "'");
      return cards;
    }
    // Leave room for "&'"; normalise_header's key limit guarantees one character fits.
    for (; pos < value.size(); ++pos) {
      const std::string e = escaped(value[pos]);
      if (card.size() + e.size() + 2 > 80) break;
      card += e;
    }
    cards.push_back(card + "&'");
    card = "CONTINUE  '";
  }
}

// ---- checkpoint ---------------------------------------------------------------------------------

struct Checkpoint {
  long long rows = 0;
  long long text_bytes = 0;
  PositionColumns positions = PositionColumns::kGrid;
  bool has_text = false;
  std::string fingerprint;
};

std::string serialise(const Checkpoint& c) {
  std::string out(kCheckpointMagic);
  out += "\nrows " + std::to_string(c.rows);
  out += "\ntext_bytes " + std::to_string(c.text_bytes);
  out += c.positions == PositionColumns::kGrid ? "\npositions grid" : "\npositions catalogue";
  out += c.has_text ? "\ntext yes" : "\ntext no";
  // Length-prefixed: a fingerprint may hold any byte, newlines included.
  out += "\nfingerprint " + std::to_string(c.fingerprint.size()) + "\n" + c.fingerprint + "\nend\n";
  return out;
}

// Throws "PATH is corrupt: ..." when `text` is not a checkpoint this writer wrote.
Checkpoint parse_checkpoint(std::string_view text, const std::string& path) {
  auto bad = [&](const char* what) { fail(path + " is corrupt: " + what); };
  auto line = [&] {
    const std::size_t nl = text.find('\n');
    if (nl == std::string_view::npos) bad("truncated");
    const std::string_view out = text.substr(0, nl);
    text.remove_prefix(nl + 1);
    return out;
  };
  auto number = [&](std::string_view name) {
    const std::string_view l = line();
    long long v = -1;
    if (l.starts_with(name) && l.size() > name.size() && l[name.size()] == ' ') {
      const char* last = l.data() + l.size();
      const auto [end, ec] = std::from_chars(l.data() + name.size() + 1, last, v);
      if (ec != std::errc() || end != last) v = -1;
    }
    if (v < 0) bad("a count is not a non-negative integer");
    return v;
  };
  if (line() != kCheckpointMagic) bad("not a stampede checkpoint");
  Checkpoint c;
  c.rows = number("rows");
  c.text_bytes = number("text_bytes");
  const std::string_view positions = line();
  if (positions != "positions grid" && positions != "positions catalogue") bad("bad positions");
  c.positions =
      positions == "positions grid" ? PositionColumns::kGrid : PositionColumns::kCatalogue;
  const std::string_view has_text = line();
  if (has_text != "text yes" && has_text != "text no") bad("bad text line");
  c.has_text = has_text == "text yes";
  const auto fp_size = static_cast<std::size_t>(number("fingerprint"));
  if (fp_size > text.size()) bad("truncated fingerprint");
  c.fingerprint = std::string(text.substr(0, fp_size));
  if (text.substr(fp_size) != "\nend\n") bad("truncated or trailing bytes");
  return c;
}

// ---- text formatting ----------------------------------------------------------------------------

// to_chars is locale-independent; for doubles, precision 17 "general" is printf's %.17g, which
// reads back bitwise ("nan", "inf" included).
void append_value(std::string* out, double v) {
  char buf[32];
  const auto r = std::to_chars(buf, buf + sizeof buf, v, std::chars_format::general, 17);
  out->append(buf, r.ptr);
}
void append_value(std::string* out, std::int64_t v) {
  char buf[24];
  const auto r = std::to_chars(buf, buf + sizeof buf, v);
  out->append(buf, r.ptr);
}

std::string text_header_line(const std::vector<Column>& columns) {
  std::string line = "#";
  for (const Column& c : columns) (line += ' ') += c.name;
  return line + "\n";
}

bool compressed_name(const std::string& path) {
  const std::string p = upper(path);
  return p.ends_with(".GZ") || p.ends_with(".FZ") || p.ends_with(".Z") || p.ends_with(".BZ2");
}

}  // namespace

// ---- state --------------------------------------------------------------------------------------

struct CatalogWriter::State {
  CatalogWriterOptions options;
  std::vector<Column> columns;
  std::string fits_partial, text_partial, checkpoint, checkpoint_tmp;
  std::string text_header;

  fitsfile* fits = nullptr;
  int fits_fd = -1;  // our descriptor of the FITS partial: fsync on it reaches CFITSIO's writes
  int text_fd = -1;
  long long rows = 0;        // committed
  long long text_bytes = 0;  // committed size of the text partial
  bool failed = false;
  bool finished = false;

  // Per-chunk column buffers, reused across appends.
  std::vector<double> f64;
  std::vector<LONGLONG> i64;
  std::vector<int> i32;
  std::vector<unsigned int> u32;
  std::string text;

  explicit State(const CatalogWriterOptions& o)
      : options(o),
        columns(columns_for(o.positions)),
        fits_partial(o.path + ".partial"),
        text_partial(o.text_path.empty() ? "" : o.text_path + ".partial"),
        checkpoint(o.path + ".checkpoint"),
        checkpoint_tmp(o.path + ".checkpoint.tmp"),
        text_header(text_header_line(columns)),
        f64(kChunkRows),
        i64(kChunkRows),
        i32(kChunkRows),
        u32(kChunkRows) {}

  State(const State&) = delete;
  State& operator=(const State&) = delete;

  // Closing a FITS file with uncommitted rows is harmless: resume cuts back to the checkpoint.
  ~State() { close_quietly(); }

  void close_quietly() noexcept {
    if (fits != nullptr) {
      int status = 0;
      fits_close_file(fits, &status);
      if (status != 0) fits_clear_errmsg();
      fits = nullptr;
    }
    if (fits_fd >= 0) ::close(fits_fd);
    if (text_fd >= 0) ::close(text_fd);
    fits_fd = text_fd = -1;
  }

  bool has_text() const { return !text_partial.empty(); }

  [[noreturn]] void fits_fail(int status, const std::string& what) {
    fail("cannot " + what + " '" + fits_partial + "': " + fits_text(status));
  }
  void check(int status, const std::string& what) {
    if (status != 0) fits_fail(status, what);
  }

  void write_checkpoint(long long new_rows, long long new_text_bytes) {
    const Checkpoint c{new_rows, new_text_bytes, options.positions, has_text(),
                       options.fingerprint};
    const int fd = ::open(checkpoint_tmp.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0666);
    if (fd < 0) fail_errno("cannot create '" + checkpoint_tmp + "'");
    try {
      write_all(fd, serialise(c), checkpoint_tmp);
      fsync_or_throw(fd, checkpoint_tmp);
    } catch (...) {
      ::close(fd);
      throw;
    }
    if (::close(fd) != 0) fail_errno("cannot close '" + checkpoint_tmp + "'");
    if (::rename(checkpoint_tmp.c_str(), checkpoint.c_str()) != 0) {
      fail_errno("cannot rename '" + checkpoint_tmp + "' to '" + checkpoint + "'");
    }
    fsync_directory(checkpoint);
  }

  void write_table_header(const std::vector<std::pair<std::string, std::string>>& header) {
    const int n = static_cast<int>(columns.size());
    std::vector<char*> ttype(n), tform_v(n), tunit(n);
    for (int i = 0; i < n; ++i) {
      // CFITSIO's API takes char* but does not write through these.
      ttype[i] = const_cast<char*>(columns[i].name);
      tform_v[i] = const_cast<char*>(tform(columns[i].type));
      tunit[i] = const_cast<char*>(columns[i].unit);
    }
    int status = 0;
    fits_create_tbl(fits, BINARY_TBL, 0, n, ttype.data(), tform_v.data(), tunit.data(), "RESULTS",
                    &status);
    check(status, "create the RESULTS table in");
    for (int i = 0; i < n; ++i) {
      const std::string key = "TCOMM" + std::to_string(i + 1);
      fits_write_key_str(fits, key.c_str(), columns[i].description, "", &status);
    }
    fits_write_comment(fits, "x0, y0: fitted centroid, 0-based pixels within the stamp (pixel "
                       "centres at integers)", &status);
    if (options.positions == PositionColumns::kCatalogue) {
      fits_write_comment(fits, "x_image, y_image: catalogue position, FITS 1-based image pixels",
                         &status);
    }
    fits_write_comment(fits, "NaN in a D column: not computed", &status);
    for (int s = 0; s < kNumStatuses; ++s) {
      const auto fs = static_cast<FitStatus>(s);
      const std::string key = "STATUS" + std::to_string(s);
      const std::string comment = "status " + std::to_string(s) +
                                  (IsUsable(fs) ? ": parameters usable" : ": not usable");
      fits_write_key_str(fits, key.c_str(), ToString(fs), comment.c_str(), &status);
    }
    for (const FlagDoc& f : kFlagDocs) {
      const std::string text = "flags bit " + std::to_string(std::countr_zero(f.bit)) + " (" +
                               std::to_string(f.bit) + "): " + f.text;
      fits_write_comment(fits, text.c_str(), &status);
    }
    check(status, "write the table description to");
    for (const auto& [key, value] : header) {
      if (is_standard_key(key)) {
        fits_update_key_longstr(fits, key.c_str(), value.c_str(), "", &status);
      } else {
        for (const std::string& card : hierarch_cards(key, value)) {
          fits_write_record(fits, card.c_str(), &status);
        }
      }
      check(status, "write header key '" + key + "' to");
    }
  }

  // Brings the on-disk state of both partials up to the present and records it in the checkpoint.
  void commit(long long new_rows, long long new_text_bytes) {
    int status = 0;
    fits_flush_file(fits, &status);  // also rewrites NAXIS2 and the data fill
    check(status, "flush");
    fsync_or_throw(fits_fd, fits_partial);
    if (has_text()) fsync_or_throw(text_fd, text_partial);
    write_checkpoint(new_rows, new_text_bytes);
    rows = new_rows;
    text_bytes = new_text_bytes;
  }

  // Rows [first, first + chunk.size()) of the table, 0-based.
  long long write_chunk(std::span<const ObjectRecord> chunk, long long first) {
    const auto n = static_cast<LONGLONG>(chunk.size());
    int status = 0;
    for (std::size_t c = 0; c < columns.size(); ++c) {
      const Column& col = columns[c];
      const int colnum = static_cast<int>(c) + 1;
      switch (col.type) {
        case ColType::kF64:
          for (std::size_t i = 0; i < chunk.size(); ++i) f64[i] = col.real(chunk[i]);
          fits_write_col(fits, TDOUBLE, colnum, first + 1, 1, n, f64.data(), &status);
          break;
        case ColType::kI64:
          for (std::size_t i = 0; i < chunk.size(); ++i) i64[i] = col.integer(chunk[i]);
          fits_write_col(fits, TLONGLONG, colnum, first + 1, 1, n, i64.data(), &status);
          break;
        case ColType::kI32:
          for (std::size_t i = 0; i < chunk.size(); ++i) {
            i32[i] = static_cast<int>(col.integer(chunk[i]));
          }
          fits_write_col(fits, TINT, colnum, first + 1, 1, n, i32.data(), &status);
          break;
        case ColType::kU32:
          for (std::size_t i = 0; i < chunk.size(); ++i) {
            u32[i] = static_cast<unsigned int>(col.integer(chunk[i]));
          }
          fits_write_col(fits, TUINT, colnum, first + 1, 1, n, u32.data(), &status);
          break;
      }
      if (status != 0) fits_fail(status, std::string("write column '") + col.name + "' of");
    }
    if (!has_text()) return 0;
    text.clear();
    for (const ObjectRecord& r : chunk) {
      for (std::size_t c = 0; c < columns.size(); ++c) {
        if (c > 0) text += ' ';
        const Column& col = columns[c];
        if (col.type == ColType::kF64) {
          append_value(&text, col.real(r));
        } else {
          append_value(&text, col.integer(r));
        }
      }
      text += '\n';
    }
    write_all(text_fd, text, text_partial);
    return static_cast<long long>(text.size());
  }

  void require_usable(const char* what) const {
    if (finished) fail(std::string("cannot ") + what + " '" + options.path + "': already finished");
    if (failed) {
      fail(std::string("cannot ") + what + " '" + options.path +
           "': an earlier write failed; resume the run to continue");
    }
  }

  // Cuts the FITS partial back to `committed` rows: the bytes after them are dropped and the fill
  // of the last block zeroed, and NAXIS2 set (a crash during a flush may have written a larger
  // one). The result is byte-identical to the file as it was at that commit.
  void repair_fits(long long committed) {
    const std::string corrupt = fits_partial + " is corrupt: ";
    int status = 0;
    fits_open_diskfile(&fits, fits_partial.c_str(), READONLY, &status);
    if (status != 0) {
      fits = nullptr;
      fail(corrupt + "cannot open it as FITS: " + fits_text(status));
    }
    LONGLONG naxis1 = 0, naxis2 = 0, headstart = 0, datastart = 0, dataend = 0;
    int hdunum = 0, ncols = 0;
    fits_movnam_hdu(fits, BINARY_TBL, const_cast<char*>("RESULTS"), 0, &status);
    fits_get_hdu_num(fits, &hdunum);
    fits_get_num_cols(fits, &ncols, &status);
    fits_read_key(fits, TLONGLONG, "NAXIS1", &naxis1, nullptr, &status);
    fits_get_num_rowsll(fits, &naxis2, &status);
    fits_get_hduaddrll(fits, &headstart, &datastart, &dataend, &status);
    if (status != 0) fail(corrupt + "no readable RESULTS table: " + fits_text(status));
    std::string why;
    if (hdunum != 2 || ncols != static_cast<int>(columns.size()) || naxis1 != row_bytes(columns)) {
      why = "its RESULTS table does not have this writer's layout";
    }
    for (int c = 0; c < ncols && why.empty(); ++c) {
      char name[FLEN_VALUE] = {};
      const std::string key = "TTYPE" + std::to_string(c + 1);
      int key_status = 0;
      fits_read_key(fits, TSTRING, key.c_str(), name, nullptr, &key_status);
      if (key_status != 0 || columns[c].name != std::string(name)) {
        why = "column " + std::to_string(c + 1) + " is not '" + columns[c].name + "'";
        if (key_status != 0) fits_clear_errmsg();
      }
    }
    fits_close_file(fits, &status);
    fits = nullptr;
    if (status != 0) {
      fits_clear_errmsg();
      status = 0;
    }
    if (!why.empty()) fail(corrupt + why);
    if (naxis2 < committed) {
      fail(corrupt + "it has " + std::to_string(naxis2) + " rows but " + checkpoint + " commits " +
           std::to_string(committed));
    }

    const long long data_end = datastart + committed * naxis1;
    const long long padded = (data_end + 2879) / 2880 * 2880;
    const int fd = ::open(fits_partial.c_str(), O_RDWR | O_CLOEXEC);
    if (fd < 0) fail_errno("cannot open '" + fits_partial + "'");
    fits_fd = fd;
    if (file_size(fd, fits_partial) < data_end) {
      fail(corrupt + "it is shorter than the " + std::to_string(committed) + " committed rows");
    }
    // Truncating then extending zeroes the fill: rows beyond NAXIS2 may have reached the disk
    // from CFITSIO's buffers before the crash.
    if (::ftruncate(fd, data_end) != 0 || ::ftruncate(fd, padded) != 0) {
      fail_errno("cannot truncate '" + fits_partial + "'");
    }

    fits_open_diskfile(&fits, fits_partial.c_str(), READWRITE, &status);
    if (status != 0) {
      fits = nullptr;
      fits_fail(status, "reopen");
    }
    fits_movabs_hdu(fits, 2, nullptr, &status);
    if (naxis2 != committed) {
      // "&" keeps the card's comment, so the header matches an uninterrupted run's.
      fits_update_key_lng(fits, "NAXIS2", committed, "&", &status);
      fits_set_hdustruc(fits, &status);  // re-read the structure after changing NAXIS2
      fits_flush_file(fits, &status);
    }
    check(status, "restore the committed rows of");
    fsync_or_throw(fd, fits_partial);
  }

  // Cuts the text partial back to `committed` bytes, checking that they end a line of this layout.
  void repair_text(long long committed) {
    const std::string corrupt = text_partial + " is corrupt: ";
    text_fd = ::open(text_partial.c_str(), O_RDWR | O_CLOEXEC);
    if (text_fd < 0) fail_errno("cannot open '" + text_partial + "'");
    const long long size = file_size(text_fd, text_partial);
    if (size < committed || committed < static_cast<long long>(text_header.size())) {
      fail(corrupt + "it is shorter than the committed " + std::to_string(committed) + " bytes");
    }
    std::string head(text_header.size(), '\0');
    char last = 0;
    if (::pread(text_fd, head.data(), head.size(), 0) != static_cast<ssize_t>(head.size()) ||
        ::pread(text_fd, &last, 1, committed - 1) != 1) {
      fail_errno("cannot read '" + text_partial + "'");
    }
    if (head != text_header) fail(corrupt + "its header line is not this writer's columns");
    if (last != '\n') fail(corrupt + "the committed bytes do not end a line");
    if (::ftruncate(text_fd, committed) != 0) fail_errno("cannot truncate '" + text_partial + "'");
    if (::lseek(text_fd, committed, SEEK_SET) != committed) {
      fail_errno("cannot seek in '" + text_partial + "'");
    }
    fsync_or_throw(text_fd, text_partial);
  }
};

namespace {

void validate(const CatalogWriterOptions& o) {
  if (o.path.empty()) fail("catalogue path is empty");
  if (compressed_name(o.path) || compressed_name(o.text_path)) {
    const std::string& p = compressed_name(o.path) ? o.path : o.text_path;
    fail("cannot write a compressed catalogue '" + p +
         "' incrementally: write it uncompressed and compress it after the run");
  }
  if (!o.text_path.empty() && o.text_path == o.path) {
    fail("text catalogue path '" + o.text_path + "' is the FITS catalogue path");
  }
}

}  // namespace

// ---- public API ---------------------------------------------------------------------------------

CatalogWriter::CatalogWriter(std::unique_ptr<State> state) : s_(std::move(state)) {}
CatalogWriter::~CatalogWriter() = default;

std::unique_ptr<CatalogWriter> CatalogWriter::create(const CatalogWriterOptions& options) {
  validate(options);
  const auto header = normalise_header(options.header);
  auto s = std::make_unique<State>(options);
  try {
    // A stale checkpoint must not outlive the partials it described.
    remove_if_present(s->checkpoint);
    remove_if_present(s->checkpoint_tmp);
    // Up-front check with the errno text: CFITSIO only says "couldn't create the named file".
    // fits_create_diskfile refuses existing files, so the probe is removed again.
    for (const std::string& p : {s->fits_partial, s->text_partial}) {
      if (p.empty()) continue;
      const int fd = ::open(p.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0666);
      if (fd < 0) fail_errno("cannot create catalogue '" + p + "'");
      ::close(fd);
    }
    remove_if_present(s->fits_partial);
    int status = 0;
    fits_create_diskfile(&s->fits, s->fits_partial.c_str(), &status);
    if (status != 0) {
      s->fits = nullptr;
      s->fits_fail(status, "create catalogue");
    }
    s->write_table_header(header);
    s->fits_fd = ::open(s->fits_partial.c_str(), O_RDONLY | O_CLOEXEC);
    if (s->fits_fd < 0) fail_errno("cannot open '" + s->fits_partial + "'");
    if (s->has_text()) {
      s->text_fd = ::open(s->text_partial.c_str(), O_WRONLY | O_TRUNC | O_CLOEXEC);
      if (s->text_fd < 0) fail_errno("cannot open '" + s->text_partial + "'");
      write_all(s->text_fd, s->text_header, s->text_partial);
      // The checkpoint's rename syncs the FITS directory; the text may live elsewhere.
      if (directory_of(s->text_partial) != directory_of(s->fits_partial)) {
        fsync_directory(s->text_partial);
      }
    }
    s->commit(0, s->has_text() ? static_cast<long long>(s->text_header.size()) : 0);
  } catch (...) {
    // Leave nothing that resume() could mistake for a run.
    s->close_quietly();
    ::unlink(s->checkpoint.c_str());
    ::unlink(s->checkpoint_tmp.c_str());
    ::unlink(s->fits_partial.c_str());
    if (s->has_text()) ::unlink(s->text_partial.c_str());
    throw;
  }
  return std::unique_ptr<CatalogWriter>(new CatalogWriter(std::move(s)));
}

std::unique_ptr<CatalogWriter> CatalogWriter::resume(const CatalogWriterOptions& options,
                                                     long long* rows_committed) {
  validate(options);
  auto s = std::make_unique<State>(options);
  for (const std::string& p : {s->checkpoint, s->fits_partial, s->text_partial}) {
    if (!p.empty() && !exists(p)) {
      fail("nothing to resume at " + options.path + ": '" + p + "' does not exist");
    }
  }
  std::string bytes;
  {
    std::ifstream in(s->checkpoint, std::ios::binary);
    bytes.assign(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
    if (in.bad()) fail("cannot read '" + s->checkpoint + "'");
  }
  const Checkpoint c = parse_checkpoint(bytes, s->checkpoint);
  if (c.fingerprint != options.fingerprint || c.positions != options.positions ||
      c.has_text != s->has_text()) {
    fail(s->checkpoint + " was written by a different run (input or configuration changed)");
  }
  s->repair_fits(c.rows);
  if (s->has_text()) s->repair_text(c.text_bytes);
  s->rows = c.rows;
  s->text_bytes = c.text_bytes;
  if (rows_committed != nullptr) *rows_committed = c.rows;
  return std::unique_ptr<CatalogWriter>(new CatalogWriter(std::move(s)));
}

void CatalogWriter::append(std::span<const ObjectRecord> rows) {
  State& s = *s_;
  s.require_usable("append to");
  if (rows.empty()) return;
  try {
    long long written = s.rows;
    long long text_bytes = s.text_bytes;
    for (std::size_t i = 0; i < rows.size(); i += kChunkRows) {
      const auto chunk = rows.subspan(i, std::min(kChunkRows, rows.size() - i));
      text_bytes += s.write_chunk(chunk, written);
      written += static_cast<long long>(chunk.size());
    }
    s.commit(written, text_bytes);
  } catch (...) {
    s.failed = true;
    throw;
  }
}

void CatalogWriter::finish() {
  State& s = *s_;
  s.require_usable("finish");
  try {
    int status = 0;
    fits_close_file(s.fits, &status);
    s.fits = nullptr;
    s.check(status, "close");
    fsync_or_throw(s.fits_fd, s.fits_partial);
    s.close_quietly();
    // The text first: once the FITS file has its final name the run counts as done.
    if (s.has_text()) {
      if (::rename(s.text_partial.c_str(), s.options.text_path.c_str()) != 0) {
        fail_errno("cannot rename '" + s.text_partial + "' to '" + s.options.text_path + "'");
      }
      fsync_directory(s.options.text_path);
    }
    if (::rename(s.fits_partial.c_str(), s.options.path.c_str()) != 0) {
      fail_errno("cannot rename '" + s.fits_partial + "' to '" + s.options.path + "'");
    }
    remove_if_present(s.checkpoint);
    remove_if_present(s.checkpoint_tmp);
    fsync_directory(s.options.path);
    s.finished = true;
  } catch (...) {
    s.failed = true;
    throw;
  }
}

long long CatalogWriter::rows() const { return s_->rows; }

std::vector<std::string> catalog_columns(PositionColumns positions) {
  std::vector<std::string> names;
  for (const Column& c : columns_for(positions)) names.emplace_back(c.name);
  return names;
}

}  // namespace stampede::io
