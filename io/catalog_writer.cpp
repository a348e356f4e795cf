// CatalogWriter implementation: the table header, commits and crash repair (see catalog_writer.hpp
// for the protocol), over the column schema (result_columns), the header cards (fits_cards) and
// the POSIX durability helpers (durable_file).
//
// CFITSIO is used directly, not through FitsFile, which lacks what this writer needs: a literal
// path (fits_create_diskfile / fits_open_diskfile, no extended syntax), typed columns with units
// (1J, 1V with TZERO, 1K), raw header records, fits_flush_file at each commit, the HDU's byte
// addresses for repair, and column writes without FitsFile::write_column_rows's per-call copy.
// Adding them to FitsFile would serve only this file; the bytes written are the same either way.
#include "io/catalog_writer.hpp"

#include <fitsio.h>

#include <algorithm>
#include <bit>
#include <cctype>
#include <cerrno>
#include <charconv>
#include <cstdint>
#include <map>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string_view>
#include <system_error>
#include <vector>

#include "engine/common/quoted_value.hpp"
#include "io/durable_file.hpp"
#include "io/fits_cards.hpp"
#include "io/fits_error.hpp"

namespace stampede::io {
namespace {

const char* tform(ColumnType t) {
  switch (t) {
    case ColumnType::kInt64: return "1K";
    case ColumnType::kInt32: return "1J";
    case ColumnType::kUInt32: return "1V";  // CFITSIO: stored as J with TZERO = 2147483648
    case ColumnType::kFloat64: return "1D";
  }
  return "?";
}

long row_bytes(std::span<const ResultColumn> columns) {
  long n = 0;
  for (const ResultColumn& c : columns) {
    n += (c.type == ColumnType::kInt64 || c.type == ColumnType::kFloat64) ? 8 : 4;
  }
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
              kFlagEdge == 1u << 16 && kFlagPsfFailure == 1u << 17 && kFlagMetacalFailure == 1u << 18 &&
              kFlagNoUsableEpoch == 1u << 19 && kFlagTooMasked == 1u << 20 && kFlagBadZeroPoint == 1u << 21 &&
                  kFlagBandLeftOut == 1u << 22 && kFlagPsfCutoutDropped == 1u << 23,
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
    {kFlagMetacalFailure, "metacal: pixels masked or a sheared fit failed"},
    {kFlagNoUsableEpoch, "survey: no cutout could be used"},
    {kFlagTooMasked, "survey: unmasked fraction below the minimum"},
    {kFlagBadZeroPoint, "survey: a cutout dropped for its image's magzp"},
    {kFlagBandLeftOut, "multi-band: a band unusable and left out"},
    {kFlagPsfCutoutDropped, "survey: a cutout dropped for its PSF"},
};
constexpr int kNumStatuses = 7;  // FitStatus::kOk .. kPsfFailure
static_assert(static_cast<int>(FitStatus::kPsfFailure) == kNumStatuses - 1,
              "FitStatus changed: update kNumStatuses");

// Rows per fits_write_col call. A chunk spans at most 256 * 200 bytes = 50 KiB of table, inside
// CFITSIO's 40 x 2880-byte buffer pool, so writing it column by column touches each buffer from
// memory; a whole large batch per column would evict and re-read blocks once per column.
constexpr std::size_t kChunkRows = 256;

constexpr std::string_view kCheckpointMagic = "stampede catalogue checkpoint 1";

[[noreturn]] void fail(const std::string& what) { throw CatalogError(what); }

// The writer promises CatalogError for every failure; durable_file reports FileError with the same
// kind of message (path and system reason), passed on unchanged.
template <typename Fn>
decltype(auto) catalog_errors(Fn&& fn) {
  try {
    return fn();
  } catch (const FileError& e) {
    throw CatalogError(e.what());
  }
}

std::string upper(std::string s) {
  for (char& c : s) c = static_cast<char>(std::toupper(static_cast<unsigned char>(c)));
  return s;
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
  out += "\npositions ";
  out += position_name(c.positions);
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
  std::string_view positions = line();
  bool known = false;
  if (positions.starts_with("positions ")) {
    positions.remove_prefix(10);
    for (PositionColumns p : {PositionColumns::kGrid, PositionColumns::kCatalogue, PositionColumns::kSurvey})
      if (positions == position_name(p)) c.positions = p, known = true;
  }
  if (!known) bad("bad positions");
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

std::string text_header_line(std::span<const ResultColumn> columns) {
  std::string line = "#";
  for (const ResultColumn& c : columns) (line += ' ') += c.name;
  return line + "\n";
}

// What differs between two fingerprints, as ": it records 'A', this run has 'B'" ("" when only the
// layout or the text output differs). Lines are "KEY=value" (an option or header key) or "role
// path: digest" (a file); those in one fingerprint only are compared, not lines at the same place,
// which a file more or less (another meds_psf_dir finds other PSFEx models) would misalign. An
// option changed is named first, as the cause; then a file of the same role; then whatever differs.
// A line may name a file: shown whole, as paths are.
std::string first_difference(std::string_view recorded, std::string_view current) {
  auto lines = [](std::string_view text) {
    std::vector<std::string_view> out;
    while (!text.empty()) {
      const std::string_view line = text.substr(0, text.find('\n'));
      out.push_back(line);
      text.remove_prefix(std::min(text.size(), line.size() + 1));
    }
    return out;
  };
  auto only_in = [](std::vector<std::string_view> a, std::vector<std::string_view> b) {  // a - b, in a's order
    std::vector<std::string_view> out;
    for (const std::string_view line : a) {
      const auto at = std::find(b.begin(), b.end(), line);
      if (at == b.end()) out.push_back(line);
      else b.erase(at);
    }
    return out;
  };
  const std::vector<std::string_view> a = lines(recorded), b = lines(current);
  const std::vector<std::string_view> only_a = only_in(a, b), only_b = only_in(b, a);
  auto quoted = [](std::string_view line) { return quoted_value(line, kQuotedPathMaxBytes); };
  auto option_key = [](std::string_view line) {
    const std::size_t eq = line.find('=');
    return eq == std::string_view::npos || line.find(' ') < eq ? std::string_view() : line.substr(0, eq + 1);
  };
  auto file_role = [](std::string_view line) {
    const std::size_t space = line.find(' ');
    return space == std::string_view::npos || line.find('=') < space ? std::string_view() : line.substr(0, space + 1);
  };
  for (auto key : {+option_key, +file_role})
    for (const std::string_view x : only_a)
      for (const std::string_view y : only_b)
        if (!key(x).empty() && key(x) == key(y)) return ": it records " + quoted(x) + ", this run has " + quoted(y);
  if (!only_a.empty() && !only_b.empty())
    return ": it records " + quoted(only_a.front()) + ", this run has " + quoted(only_b.front());
  if (!only_a.empty()) return ": it records " + quoted(only_a.front()) + ", which this run has not";
  if (!only_b.empty()) return ": this run has " + quoted(only_b.front()) + ", which it does not record";
  for (std::size_t k = 0; k < a.size() && k < b.size(); ++k)  // the same lines in another order
    if (a[k] != b[k]) return ": it records " + quoted(a[k]) + ", this run has " + quoted(b[k]);
  return "";
}

bool compressed_name(const std::string& path) {
  const std::string p = upper(path);
  return p.ends_with(".GZ") || p.ends_with(".FZ") || p.ends_with(".Z") || p.ends_with(".BZ2");
}

}  // namespace

// ---- state --------------------------------------------------------------------------------------

struct CatalogWriter::State {
  CatalogWriterOptions options;
  ResultSchema schema;
  std::span<const ResultColumn> columns;
  std::string fits_partial, text_partial, checkpoint, checkpoint_tmp;
  std::string text_header;

  fitsfile* fits = nullptr;
  DurableFile fits_file;  // our descriptor of the FITS partial: fsync on it reaches CFITSIO's writes
  DurableFile text_file;
  long long rows = 0;        // committed
  long long text_bytes = 0;  // committed size of the text partial
  bool failed = false;
  bool finished = false;
  // A write failed after rows were committed: abandon() keeps the partials and the checkpoint,
  // which still describe those rows, so the run resumes once room is made.
  bool keep_for_resume = false;

  // Per-chunk column buffers, reused across appends.
  std::vector<double> f64;
  std::vector<LONGLONG> i64;
  std::vector<int> i32;
  std::vector<unsigned int> u32;
  std::string text;

  explicit State(const CatalogWriterOptions& o)
      : options(o),
        schema(o.positions, o.metacal, o.bands),
        columns(schema.columns()),
        fits_partial(o.path + ".partial"),
        text_partial(o.text_path.empty() ? "" : o.text_path + ".partial"),
        checkpoint(o.path + ".checkpoint"),
        checkpoint_tmp(temporary_path(checkpoint)),
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
    fits_file = DurableFile();
    text_file = DurableFile();
  }

  bool has_text() const { return !text_partial.empty(); }

  // `error`: errno just after the failed CFITSIO call (CFITSIO's file driver leaves the failed
  // write's there). For a write, what ran out (space_exhausted_reason) is named first.
  [[noreturn]] void fits_fail(int status, const std::string& what, int error = 0) {
    const std::string reason = status == WRITE_ERROR ? space_exhausted_reason(fits_partial, error) : "";
    if (reason.empty()) fail("cannot " + what + " '" + fits_partial + "': " + cfitsio_status_text(status));
    fits_clear_errmsg();
    fail("cannot " + what + " '" + fits_partial + "': " + reason + " (CFITSIO status " + std::to_string(status) + ")");
  }
  void check(int status, const std::string& what, int error = 0) {
    if (status != 0) fits_fail(status, what, error);
  }

  void write_checkpoint(long long new_rows, long long new_text_bytes) {
    const Checkpoint c{new_rows, new_text_bytes, options.positions, has_text(),
                       options.fingerprint};
    replace_durably(checkpoint, serialise(c));
  }

  void write_table_header(const StringKeys& header) {
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
    if (options.positions == PositionColumns::kSurvey) {
      fits_write_comment(fits, "survey rows: e1 e2 in the tiles' (u, v) plane (meds, GalSim: u = -dRA", &status);
      fits_write_comment(fits, "cos(dec), v = dDec: e1 > 0 east-west, e2 > 0 north-west); x0 y0 the", &status);
      fits_write_comment(fits, "centroid's (u, v) offset from the MEDS position, arcsec", &status);
    } else {
      fits_write_comment(fits, "x0, y0: fitted centroid, 0-based pixels within the stamp (pixel "
                         "centres at integers)", &status);
    }
    if (options.positions == PositionColumns::kCatalogue) {
      fits_write_comment(fits, "x_image, y_image: catalogue position, FITS 1-based image pixels",
                         &status);
    }
    fits_write_comment(fits, "NaN in a D column: not computed", &status);
    if (!options.bands.empty()) {
      std::string bands;
      for (const std::string& b : options.bands) bands += (bands.empty() ? "" : ",") + b;
      fits_write_key_str(fits, kBandsKey, bands.c_str(), "the bands of the _<band> columns, in order", &status);
    }
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
    std::map<std::string, HeaderValueType> types;  // by the upper-case key the header holds
    for (const auto& [key, type] : options.header_types) types[upper(key)] = type;
    for (const auto& [key, value] : header) {
      const auto type = types.find(key);
      write_header_key(fits, key, value, type == types.end() ? HeaderValueType::kText : type->second, &status);
      check(status, "write header key '" + key + "' to");
    }
  }

  // Brings the on-disk state of both partials up to the present and records it in the checkpoint.
  void commit(long long new_rows, long long new_text_bytes) {
    int status = 0;
    errno = 0;
    fits_flush_file(fits, &status);  // also rewrites NAXIS2 and the data fill
    check(status, "write", errno);
    fits_file.sync();
    if (has_text()) text_file.sync();
    write_checkpoint(new_rows, new_text_bytes);
    rows = new_rows;
    text_bytes = new_text_bytes;
  }

  // Rows [first, first + chunk.size()) of the table, 0-based.
  long long write_chunk(std::span<const ObjectRecord> chunk, long long first) {
    const auto n = static_cast<LONGLONG>(chunk.size());
    int status = 0;
    errno = 0;
    for (std::size_t c = 0; c < columns.size(); ++c) {
      const ResultColumn& col = columns[c];
      const int colnum = static_cast<int>(c) + 1;
      switch (col.type) {
        case ColumnType::kFloat64:
          for (std::size_t i = 0; i < chunk.size(); ++i) f64[i] = col.real(chunk[i]);
          fits_write_col(fits, TDOUBLE, colnum, first + 1, 1, n, f64.data(), &status);
          break;
        case ColumnType::kInt64:
          for (std::size_t i = 0; i < chunk.size(); ++i) i64[i] = col.integer(chunk[i]);
          fits_write_col(fits, TLONGLONG, colnum, first + 1, 1, n, i64.data(), &status);
          break;
        case ColumnType::kInt32:
          for (std::size_t i = 0; i < chunk.size(); ++i) {
            i32[i] = static_cast<int>(col.integer(chunk[i]));
          }
          fits_write_col(fits, TINT, colnum, first + 1, 1, n, i32.data(), &status);
          break;
        case ColumnType::kUInt32:
          for (std::size_t i = 0; i < chunk.size(); ++i) {
            u32[i] = static_cast<unsigned int>(col.integer(chunk[i]));
          }
          fits_write_col(fits, TUINT, colnum, first + 1, 1, n, u32.data(), &status);
          break;
      }
      if (status != 0) fits_fail(status, std::string("write column '") + col.name + "' of", errno);
    }
    if (!has_text()) return 0;
    text.clear();
    for (const ObjectRecord& r : chunk) {
      for (std::size_t c = 0; c < columns.size(); ++c) {
        if (c > 0) text += ' ';
        const ResultColumn& col = columns[c];
        if (col.type == ColumnType::kFloat64) {
          append_value(&text, col.real(r));
        } else {
          append_value(&text, col.integer(r));
        }
      }
      text += '\n';
    }
    text_file.write_all(text);
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
      fail(corrupt + "cannot open it as FITS: " + cfitsio_status_text(status));
    }
    LONGLONG naxis1 = 0, naxis2 = 0, headstart = 0, datastart = 0, dataend = 0;
    int hdunum = 0, ncols = 0;
    fits_movnam_hdu(fits, BINARY_TBL, const_cast<char*>("RESULTS"), 0, &status);
    fits_get_hdu_num(fits, &hdunum);
    fits_get_num_cols(fits, &ncols, &status);
    fits_read_key(fits, TLONGLONG, "NAXIS1", &naxis1, nullptr, &status);
    fits_get_num_rowsll(fits, &naxis2, &status);
    fits_get_hduaddrll(fits, &headstart, &datastart, &dataend, &status);
    if (status != 0) fail(corrupt + "no readable RESULTS table: " + cfitsio_status_text(status));
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
    fits_file = DurableFile::open(fits_partial, DurableFile::Mode::kReadWrite);
    if (fits_file.size() < data_end) {
      fail(corrupt + "it is shorter than the " + std::to_string(committed) + " committed rows");
    }
    // Truncating then extending zeroes the fill: rows beyond NAXIS2 may have reached the disk
    // from CFITSIO's buffers before the crash.
    fits_file.truncate(data_end);
    fits_file.truncate(padded);

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
    fits_file.sync();
  }

  // Cuts the text partial back to `committed` bytes, checking that they end a line of this layout.
  void repair_text(long long committed) {
    const std::string corrupt = text_partial + " is corrupt: ";
    text_file = DurableFile::open(text_partial, DurableFile::Mode::kReadWrite);
    const long long size = text_file.size();
    if (size < committed || committed < static_cast<long long>(text_header.size())) {
      fail(corrupt + "it is shorter than the committed " + std::to_string(committed) + " bytes");
    }
    std::string head(text_header.size(), '\0');
    char last = 0;
    text_file.read_at(0, head);
    text_file.read_at(committed - 1, std::span<char>(&last, 1));
    if (head != text_header) fail(corrupt + "its header line is not this writer's columns");
    if (last != '\n') fail(corrupt + "the committed bytes do not end a line");
    text_file.truncate(committed);
    text_file.seek_to_end();
    text_file.sync();
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
  ignore_file_size_signal();  // a write past `ulimit -f` fails (EFBIG, reported) instead of killing the process
  StringKeys header;
  std::string why;
  if (!normalise_string_keys(options.header, &header, &why)) fail(why);
  auto s = std::make_unique<State>(options);
  catalog_errors([&] {
    try {
      // A stale checkpoint must not outlive the partials it described.
      remove_if_present(s->checkpoint);
      remove_if_present(s->checkpoint_tmp);
      // Up-front check with the errno text: CFITSIO only says "couldn't create the named file".
      // fits_create_diskfile refuses existing files, so the FITS probe is removed again; the
      // text one is the text partial.
      DurableFile::create(s->fits_partial, "catalogue");
      if (s->has_text()) s->text_file = DurableFile::create(s->text_partial, "catalogue");
      remove_if_present(s->fits_partial);
      int status = 0;
      fits_create_diskfile(&s->fits, s->fits_partial.c_str(), &status);
      if (status != 0) {
        s->fits = nullptr;
        s->fits_fail(status, "create catalogue");
      }
      s->write_table_header(header);
      s->fits_file = DurableFile::open(s->fits_partial, DurableFile::Mode::kRead);
      if (s->has_text()) {
        s->text_file.write_all(s->text_header);
        // The checkpoint's rename syncs the FITS directory; the text may live elsewhere.
        if (directory_of(s->text_partial) != directory_of(s->fits_partial)) {
          sync_directory_of(s->text_partial);
        }
      }
      s->commit(0, s->has_text() ? static_cast<long long>(s->text_header.size()) : 0);
    } catch (...) {
      // Leave nothing that resume() could mistake for a run.
      s->close_quietly();
      std::error_code ignored;
      for (const std::string& p : {s->checkpoint, s->checkpoint_tmp, s->fits_partial, s->text_partial}) {
        if (!p.empty()) std::filesystem::remove(p, ignored);
      }
      throw;
    }
  });
  return std::unique_ptr<CatalogWriter>(new CatalogWriter(std::move(s)));
}

std::unique_ptr<CatalogWriter> CatalogWriter::resume(const CatalogWriterOptions& options,
                                                     long long* rows_committed) {
  validate(options);
  ignore_file_size_signal();
  auto s = std::make_unique<State>(options);
  if (!file_exists(s->checkpoint) && !file_exists(s->fits_partial) && file_exists(options.path))
    fail("nothing to resume at " + options.path + ": it is complete (finished, so it has no '" + s->checkpoint +
         "'); refit it with --overwrite to replace it");
  for (const std::string& p : {s->checkpoint, s->fits_partial, s->text_partial}) {
    if (!p.empty() && !file_exists(p)) {
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
    fail(s->checkpoint + " was written by a different run (input or configuration changed)" +
         first_difference(c.fingerprint, options.fingerprint));
  }
  catalog_errors([&] {
    s->repair_fits(c.rows);
    if (s->has_text()) s->repair_text(c.text_bytes);
  });
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
    catalog_errors([&] {
      long long written = s.rows;
      long long text_bytes = s.text_bytes;
      for (std::size_t i = 0; i < rows.size(); i += kChunkRows) {
        const auto chunk = rows.subspan(i, std::min(kChunkRows, rows.size() - i));
        text_bytes += s.write_chunk(chunk, written);
        written += static_cast<long long>(chunk.size());
      }
      s.commit(written, text_bytes);
    });
  } catch (const CatalogError& e) {
    s.failed = true;
    if (s.rows == 0 || !s.options.keep_on_write_failure) throw;
    s.keep_for_resume = true;
    throw CatalogError(std::string(e.what()) + "; the " + std::to_string(s.rows) + " rows committed before it are kept in '" +
                       s.fits_partial + "' (with '" + s.checkpoint + "'): make room, then resume the run (stampede fit --resume)");
  } catch (...) {
    s.failed = true;
    throw;
  }
}

void CatalogWriter::finish() {
  State& s = *s_;
  s.require_usable("finish");
  bool unresumable = false;
  try {
    catalog_errors([&] {
      int status = 0;
      errno = 0;
      // Where the file ends: the last HDU's data end.
      int hdus = 0;
      LONGLONG header_start = 0, data_start = 0, data_end = 0;
      fits_get_num_hdus(s.fits, &hdus, &status);
      fits_movabs_hdu(s.fits, hdus, nullptr, &status);
      fits_get_hduaddrll(s.fits, &header_start, &data_start, &data_end, &status);
      s.check(status, "locate the end of", errno);
      fits_close_file(s.fits, &status);
      const int error = errno;
      s.fits = nullptr;
      s.check(status, "close", error);
      s.fits_file.sync();
      s.close_quietly();
      // The file must reach its end before it is named (unwritten_tail). A partial the close cut is
      // not resumable (the close rewrote committed blocks): it is removed, not kept.
      if (const std::string tail = unwritten_tail(s.fits_partial, data_end); !tail.empty()) {
        unresumable = true;
        throw CatalogError(tail +
                           "; the table is incomplete and was removed: make room, then run again (without --resume)");
      }
      // The text first: once the FITS file has its final name the run counts as done.
      if (s.has_text()) {
        rename_file(s.text_partial, s.options.text_path);
        sync_directory_of(s.options.text_path);
      }
      rename_file(s.fits_partial, s.options.path);
      remove_if_present(s.checkpoint);
      remove_if_present(s.checkpoint_tmp);
      sync_directory_of(s.options.path);
      s.finished = true;
    });
  } catch (const CatalogError& e) {
    s.failed = true;
    // Until the FITS partial is renamed the run is resumable at its last commit; after, it is done.
    if (unresumable || s.rows == 0 || !s.options.keep_on_write_failure || !file_exists(s.fits_partial)) throw;
    s.keep_for_resume = true;
    throw CatalogError(std::string(e.what()) + "; the " + std::to_string(s.rows) + " committed rows are kept in '" +
                       s.fits_partial + "' (with '" + s.checkpoint + "'): resume the run (stampede fit --resume)");
  } catch (...) {
    s.failed = true;
    throw;
  }
}

void CatalogWriter::abandon() noexcept {
  State& s = *s_;
  s.close_quietly();
  s.failed = true;
  std::error_code ignored;
  std::filesystem::remove(s.checkpoint_tmp, ignored);
  if (s.keep_for_resume) return;  // a failed write: the committed rows stay resumable
  for (const std::string& p : {s.checkpoint, s.fits_partial, s.text_partial})
    if (!p.empty()) std::filesystem::remove(p, ignored);
}

long long CatalogWriter::rows() const { return s_->rows; }

}  // namespace stampede::io
