// The fit catalogue's schema over the durable table (io/durable_table): its columns (result_columns),
// header description, and column and text writes. CFITSIO is used directly for typed columns with
// units (1J, 1V with TZERO, 1K) and column writes without FitsFile's per-call copy.
#include "io/catalog_writer.hpp"

#include <fitsio.h>

#include <algorithm>
#include <bit>
#include <cerrno>
#include <cstdint>
#include <charconv>
#include <string_view>
#include <vector>

#include "io/durable_table.hpp"

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

// The table's description: what the columns cannot say (coordinate conventions), the bands, the
// status names and the flag bits.
void describe(const CatalogWriterOptions& o, fitsfile* fits, int* status) {
  if (o.positions == PositionColumns::kSurvey) {
    fits_write_comment(fits, "survey rows: e1 e2 in the tiles' (u, v) plane (meds, GalSim: u = -dRA", status);
    fits_write_comment(fits, "cos(dec), v = dDec: e1 > 0 east-west, e2 > 0 north-west); x0 y0 the", status);
    fits_write_comment(fits, "centroid's (u, v) offset from the MEDS position, arcsec", status);
  } else {
    fits_write_comment(fits, "x0, y0: fitted centroid, 0-based pixels within the stamp (pixel centres at integers)",
                       status);
  }
  if (o.positions == PositionColumns::kCatalogue)
    fits_write_comment(fits, "x_image, y_image: catalogue position, FITS 1-based image pixels", status);
  fits_write_comment(fits, "NaN in a D column: not computed", status);
  if (!o.bands.empty()) {
    std::string bands;
    for (const std::string& b : o.bands) bands += (bands.empty() ? "" : ",") + b;
    fits_write_key_str(fits, kBandsKey, bands.c_str(), "the bands of the _<band> columns, in order", status);
  }
  for (int s = 0; s < kNumStatuses; ++s) {
    const auto fs = static_cast<FitStatus>(s);
    const std::string key = "STATUS" + std::to_string(s);
    const std::string comment = "status " + std::to_string(s) + (IsUsable(fs) ? ": parameters usable" : ": not usable");
    fits_write_key_str(fits, key.c_str(), ToString(fs), comment.c_str(), status);
  }
  for (const FlagDoc& f : kFlagDocs) {
    const std::string text = "flags bit " + std::to_string(std::countr_zero(f.bit)) + " (" + std::to_string(f.bit) +
                             "): " + f.text;
    fits_write_comment(fits, text.c_str(), status);
  }
}

DurableTableOptions table_options(const CatalogWriterOptions& o, std::span<const ResultColumn> columns) {
  DurableTableOptions t;
  t.text_path = o.text_path;
  t.text_header = o.text_path.empty() ? "" : text_header_line(columns);
  t.extname = "RESULTS";
  for (const ResultColumn& c : columns) t.columns.push_back({c.name, tform(c.type), c.unit, c.description});
  t.describe = [o](fitsfile* fits, int* status) { describe(o, fits, status); };
  static_cast<TableWriterOptions&>(t) = o;
  t.layout = std::string("fit catalogue, ") + position_name(o.positions) + " positions";
  t.keep_on_write_failure = o.keep_on_write_failure;
  return t;
}

}  // namespace

struct CatalogWriter::State {
  ResultSchema schema;
  std::span<const ResultColumn> columns;
  DurableTable* table = nullptr;  // the writer's
  // Per-chunk column buffers, reused across appends.
  std::vector<double> f64 = std::vector<double>(kChunkRows);
  std::vector<LONGLONG> i64 = std::vector<LONGLONG>(kChunkRows);
  std::vector<int> i32 = std::vector<int>(kChunkRows);
  std::vector<unsigned int> u32 = std::vector<unsigned int>(kChunkRows);
  std::string text;
  bool has_text = false;

  explicit State(const CatalogWriterOptions& o)
      : schema(o.positions, o.metacal, o.bands), columns(schema.columns()), has_text(!o.text_path.empty()) {}

  // Rows [first, first + chunk.size()) of the table, 0-based.
  void write_chunk(std::span<const ObjectRecord> chunk, long long first) {
    fitsfile* fits = table->fits();
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
          for (std::size_t i = 0; i < chunk.size(); ++i) i32[i] = static_cast<int>(col.integer(chunk[i]));
          fits_write_col(fits, TINT, colnum, first + 1, 1, n, i32.data(), &status);
          break;
        case ColumnType::kUInt32:
          for (std::size_t i = 0; i < chunk.size(); ++i) u32[i] = static_cast<unsigned int>(col.integer(chunk[i]));
          fits_write_col(fits, TUINT, colnum, first + 1, 1, n, u32.data(), &status);
          break;
      }
      table->check(status, std::string("write column '") + col.name + "' of", errno);
    }
    if (!has_text) return;
    text.clear();
    for (const ObjectRecord& r : chunk) {
      for (std::size_t c = 0; c < columns.size(); ++c) {
        if (c > 0) text += ' ';
        const ResultColumn& col = columns[c];
        if (col.type == ColumnType::kFloat64) append_value(&text, col.real(r));
        else append_value(&text, col.integer(r));
      }
      text += '\n';
    }
    table->write_text(text);
  }
};

CatalogWriter::CatalogWriter(const CatalogWriterOptions& options, bool resume) : s_(std::make_unique<State>(options)) {
  open(table_options(options, s_->columns), resume);
  s_->table = &table();
}
CatalogWriter::~CatalogWriter() = default;

std::unique_ptr<CatalogWriter> CatalogWriter::create(const CatalogWriterOptions& options) {
  return std::unique_ptr<CatalogWriter>(new CatalogWriter(options, false));
}

std::unique_ptr<CatalogWriter> CatalogWriter::resume(const CatalogWriterOptions& options) {
  return std::unique_ptr<CatalogWriter>(new CatalogWriter(options, true));
}

void CatalogWriter::append(std::span<const ObjectRecord> rows) {
  State& s = *s_;
  if (rows.empty()) return;
  const auto n = static_cast<long long>(rows.size());
  s.table->append(n, n, [&] {
    long long written = s.table->rows();
    for (std::size_t i = 0; i < rows.size(); i += kChunkRows) {
      const auto chunk = rows.subspan(i, std::min(kChunkRows, rows.size() - i));
      s.write_chunk(chunk, written);
      written += static_cast<long long>(chunk.size());
    }
  });
}


}  // namespace stampede::io
