// The metadetection catalogue; see metadetect_writer.hpp.
#include "io/metadetect_writer.hpp"

#include <fitsio.h>

#include <cctype>
#include <cerrno>
#include <charconv>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string_view>

#include "engine/metacal/metacal_type.hpp"
#include "io/durable_file.hpp"
#include "io/fits_cards.hpp"
#include "io/fits_error.hpp"

namespace stampede::io {
namespace {

struct Column {
  const char* name;
  const char* tform;
  const char* unit;
  const char* comment;
};

constexpr Column kColumns[] = {
    {"cell", "1K", "", "cell number in the run (input order)"},
    {"shear_type", "7A", "", "metacal image: noshear 1p 1m 2p 2m"},
    {"id", "1J", "", "detection number in its cell and image; -1: the cell failed"},
    {"x", "1D", "pixel", "centroid (exp, bd: the fit's), 0-based column of the input image"},
    {"y", "1D", "pixel", "centroid (exp, bd: the fit's), 0-based row of the input image"},
    {"u", "1D", "arcsec", "x times the pixel scale"},
    {"v", "1D", "arcsec", "y times the pixel scale"},
    {"e1", "1D", "", "(Mxx - Myy) / T under the weight; exp, bd: (a - b) / (a + b)"},
    {"e2", "1D", "", "2 Mxy / T"},
    {"e1_err", "1D", "", "for white noise of the image's variance"},
    {"e2_err", "1D", "", "for white noise of the image's variance"},
    {"T", "1D", "arcsec2", "Mxx + Myy (weighted; pgauss: pre-PSF; exp, bd: the model's)"},
    {"T_ratio", "1D", "", "T over the reconvolved PSF's T"},
    {"psf_T", "1D", "arcsec2", "the reconvolved PSF's T under the weight"},
    {"flux", "1D", "", "sum of weight x pixel values (exp, bd: the model's flux)"},
    {"snr", "1D", "", "flux over its error"},
    {"mfrac", "1D", "", "masked fraction of the stamp"},
    {"box_size", "1J", "pixel", "the stamp's side"},
    {"isophotal_area", "1J", "pixel", "pixels above the detection threshold"},
    {"sep_flags", "1J", "", "Source Extractor: 1 deblended, 2 on the edge, 8 singular"},
    {"flags", "1J", "", "1 measurement failed, 2 edge, 4 masked pixels, 8 cell failed"},
};
constexpr int kNumColumns = static_cast<int>(std::size(kColumns));
constexpr std::string_view kMagic = "stampede metadetect checkpoint 1";

[[noreturn]] void fail(const std::string& what) { throw CatalogError(what); }

std::string serialise(long long rows, long long cells, const std::string& fingerprint) {
  return std::string(kMagic) + "\nrows " + std::to_string(rows) + "\ncells " + std::to_string(cells) +
         "\nfingerprint " + std::to_string(fingerprint.size()) + "\n" + fingerprint + "\nend\n";
}

struct Checkpoint {
  long long rows = 0, cells = 0;
  std::string fingerprint;
};

Checkpoint parse(std::string_view text, const std::string& path) {
  auto bad = [&](const char* what) { fail(path + " is corrupt: " + what); };
  auto number = [&](std::string_view name) {
    const std::size_t nl = text.find('\n');
    if (nl == std::string_view::npos) bad("truncated");
    const std::string_view l = text.substr(0, nl);
    text.remove_prefix(nl + 1);
    long long v = -1;
    if (l.starts_with(name) && l.size() > name.size() + 1 && l[name.size()] == ' ') {
      const auto [end, ec] = std::from_chars(l.data() + name.size() + 1, l.data() + l.size(), v);
      if (ec != std::errc() || end != l.data() + l.size()) v = -1;
    }
    if (v < 0) bad("a count is not a non-negative integer");
    return v;
  };
  if (!text.starts_with(std::string(kMagic) + "\n")) bad("not a stampede metadetect checkpoint");
  text.remove_prefix(kMagic.size() + 1);
  Checkpoint c;
  c.rows = number("rows");
  c.cells = number("cells");
  const auto n = static_cast<std::size_t>(number("fingerprint"));
  if (n > text.size()) bad("truncated fingerprint");
  c.fingerprint = std::string(text.substr(0, n));
  if (text.substr(n) != "\nend\n") bad("truncated or trailing bytes");
  return c;
}

}  // namespace

std::vector<std::string> metadetect_columns(const std::vector<std::string>& bands) {
  std::vector<std::string> out;
  for (const Column& c : kColumns) out.emplace_back(c.name);
  for (const std::string& b : bands) out.push_back("flux_" + b);
  for (const std::string& b : bands) out.push_back("snr_" + b);
  return out;
}

struct MetadetectWriter::State {
  MetadetectWriterOptions options;
  std::string partial, checkpoint;
  fitsfile* fits = nullptr;
  DurableFile file;  // fsync reaches CFITSIO's writes
  long long rows = 0, cells = 0;
  bool failed = false, finished = false, keep_for_resume = false;
  std::vector<double> f64;
  std::vector<LONGLONG> i64;
  std::vector<int> i32;
  std::vector<char*> strings;

  explicit State(const MetadetectWriterOptions& o)
      : options(o), partial(o.path + ".partial"), checkpoint(o.path + ".checkpoint") {}
  ~State() { close_quietly(); }

  void close_quietly() noexcept {
    if (fits) {
      int status = 0;
      fits_close_file(fits, &status);
      if (status) fits_clear_errmsg();
      fits = nullptr;
    }
    file = DurableFile();
  }
  void check(int status, const std::string& what, int error = 0) {
    if (status == 0) return;
    const std::string reason = status == WRITE_ERROR ? space_exhausted_reason(partial, error) : "";
    fits_clear_errmsg();
    fail("cannot " + what + " '" + partial + "': " + (reason.empty() ? cfitsio_status_text(status) : reason));
  }
  void commit(long long new_rows, long long new_cells) {
    int status = 0;
    errno = 0;
    fits_flush_file(fits, &status);
    check(status, "write", errno);
    file.sync();
    replace_durably(checkpoint, serialise(new_rows, new_cells, options.fingerprint));
    rows = new_rows, cells = new_cells;
  }
  void write_rows(std::span<const MetadetectRow> r) {
    const auto n = static_cast<LONGLONG>(r.size());
    const LONGLONG first = rows + 1;
    f64.resize(r.size()), i64.resize(r.size()), i32.resize(r.size()), strings.resize(r.size());
    int status = 0;
    errno = 0;
    auto doubles = [&](int col, auto get) {
      for (std::size_t i = 0; i < r.size(); ++i) f64[i] = get(r[i]);
      fits_write_col(fits, TDOUBLE, col, first, 1, n, f64.data(), &status);
    };
    auto ints = [&](int col, auto get) {
      for (std::size_t i = 0; i < r.size(); ++i) i32[i] = static_cast<int>(get(r[i]));
      fits_write_col(fits, TINT, col, first, 1, n, i32.data(), &status);
    };
    for (std::size_t i = 0; i < r.size(); ++i) i64[i] = r[i].cell;
    fits_write_col(fits, TLONGLONG, 1, first, 1, n, i64.data(), &status);
    for (std::size_t i = 0; i < r.size(); ++i)
      strings[i] = const_cast<char*>(metacal_type_name(static_cast<MetacalType>(r[i].shear_type)));
    fits_write_col(fits, TSTRING, 2, first, 1, n, strings.data(), &status);
    ints(3, [](const MetadetectRow& x) { return x.id; });
    doubles(4, [](const MetadetectRow& x) { return x.x; });
    doubles(5, [](const MetadetectRow& x) { return x.y; });
    doubles(6, [](const MetadetectRow& x) { return x.u; });
    doubles(7, [](const MetadetectRow& x) { return x.v; });
    doubles(8, [](const MetadetectRow& x) { return x.e1; });
    doubles(9, [](const MetadetectRow& x) { return x.e2; });
    doubles(10, [](const MetadetectRow& x) { return x.e1_err; });
    doubles(11, [](const MetadetectRow& x) { return x.e2_err; });
    doubles(12, [](const MetadetectRow& x) { return x.t; });
    doubles(13, [](const MetadetectRow& x) { return x.t_ratio; });
    doubles(14, [](const MetadetectRow& x) { return x.psf_t; });
    doubles(15, [](const MetadetectRow& x) { return x.flux; });
    doubles(16, [](const MetadetectRow& x) { return x.snr; });
    doubles(17, [](const MetadetectRow& x) { return x.mfrac; });
    ints(18, [](const MetadetectRow& x) { return x.box_size; });
    ints(19, [](const MetadetectRow& x) { return x.isophotal_area; });
    ints(20, [](const MetadetectRow& x) { return x.sep_flags; });
    ints(21, [](const MetadetectRow& x) { return x.flags; });
    const int nb = static_cast<int>(options.bands.size());
    for (int b = 0; b < nb; ++b) {
      doubles(kNumColumns + 1 + b, [b](const MetadetectRow& x) { return x.band_flux[static_cast<std::size_t>(b)]; });
      doubles(kNumColumns + 1 + nb + b, [b](const MetadetectRow& x) { return x.band_snr[static_cast<std::size_t>(b)]; });
    }
    check(status, "write rows to", errno);
  }
  int columns() const { return kNumColumns + 2 * static_cast<int>(options.bands.size()); }
  void create_table(const StringKeys& header) {
    const std::vector<std::string> names = metadetect_columns(options.bands);
    std::vector<std::string> comments;
    for (const Column& c : kColumns) comments.emplace_back(c.comment);
    for (const std::string& b : options.bands) comments.push_back("band " + b + ": its stamp's flux under the weight");
    for (const std::string& b : options.bands) comments.push_back("band " + b + ": its stamp's flux over its error");
    const int n = columns();
    std::vector<char*> ttype(n), tform(n), tunit(n);
    for (int i = 0; i < n; ++i) {
      ttype[i] = const_cast<char*>(names[i].c_str());
      tform[i] = const_cast<char*>(i < kNumColumns ? kColumns[i].tform : "1D");
      tunit[i] = const_cast<char*>(i < kNumColumns ? kColumns[i].unit : "");
    }
    int status = 0;
    fits_create_tbl(fits, BINARY_TBL, 0, n, ttype.data(), tform.data(), tunit.data(), "METADETECT", &status);
    for (int i = 0; i < n && status == 0; ++i) {
      const std::string key = "TCOMM" + std::to_string(i + 1);
      fits_update_key_str(fits, key.c_str(), comments[i].c_str(), nullptr, &status);
    }
    check(status, "write the table description to");
    std::map<std::string, HeaderValueType> types;
    for (const auto& [key, type] : options.header_types) {
      std::string k = key;
      for (char& c : k) c = static_cast<char>(std::toupper(static_cast<unsigned char>(c)));
      types[k] = type;
    }
    for (const auto& [key, value] : header) {
      const auto t = types.find(key);
      write_header_key(fits, key, value, t == types.end() ? HeaderValueType::kText : t->second, &status);
      check(status, "write header key '" + key + "' to");
    }
  }
  // Cuts the partial back to the committed rows (a kill may have left more on disk).
  void reopen_at(long long committed) {
    int status = 0;
    fits_open_diskfile(&fits, partial.c_str(), READWRITE, &status);
    if (status) {
      fits = nullptr;
      fail(partial + " is corrupt: cannot open it as FITS: " + cfitsio_status_text(status));
    }
    fits_movnam_hdu(fits, BINARY_TBL, const_cast<char*>("METADETECT"), 0, &status);
    int ncols = 0;
    LONGLONG naxis2 = 0;
    fits_get_num_cols(fits, &ncols, &status);
    fits_get_num_rowsll(fits, &naxis2, &status);
    if (status) fail(partial + " is corrupt: no readable METADETECT table: " + cfitsio_status_text(status));
    if (ncols != columns()) fail(partial + " is corrupt: its table does not have this writer's columns");
    if (naxis2 < committed)
      fail(partial + " is corrupt: it has " + std::to_string(naxis2) + " rows but " + checkpoint + " commits " +
           std::to_string(committed));
    if (naxis2 > committed) fits_delete_rows(fits, committed + 1, naxis2 - committed, &status);
    check(status, "cut back");
    file = DurableFile::open(partial, DurableFile::Mode::kRead);
  }
};

MetadetectWriter::MetadetectWriter(std::unique_ptr<State> s) : s_(std::move(s)) {}
MetadetectWriter::~MetadetectWriter() = default;

std::unique_ptr<MetadetectWriter> MetadetectWriter::create(const MetadetectWriterOptions& options) {
  ignore_file_size_signal();
  StringKeys header;
  std::string why;
  if (!normalise_string_keys(options.header, &header, &why)) fail(why);
  auto s = std::make_unique<State>(options);
  try {
    remove_if_present(s->checkpoint);
    DurableFile::create(s->partial, "catalogue");  // the errno text, where CFITSIO would only say "cannot create"
    remove_if_present(s->partial);
    int status = 0;
    fits_create_diskfile(&s->fits, s->partial.c_str(), &status);
    if (status) {
      s->fits = nullptr;
      s->check(status, "create catalogue");
    }
    s->create_table(header);
    s->file = DurableFile::open(s->partial, DurableFile::Mode::kRead);
    s->commit(0, 0);
  } catch (const FileError& e) {
    s->close_quietly();
    remove_if_present(s->checkpoint);
    std::error_code ignored;
    std::filesystem::remove(s->partial, ignored);
    fail(e.what());
  } catch (...) {
    s->close_quietly();
    std::error_code ignored;
    std::filesystem::remove(s->checkpoint, ignored);
    std::filesystem::remove(s->partial, ignored);
    throw;
  }
  return std::unique_ptr<MetadetectWriter>(new MetadetectWriter(std::move(s)));
}

std::unique_ptr<MetadetectWriter> MetadetectWriter::resume(const MetadetectWriterOptions& options,
                                                           long long* cells_committed) {
  ignore_file_size_signal();
  auto s = std::make_unique<State>(options);
  if (!file_exists(s->checkpoint) && !file_exists(s->partial) && file_exists(options.path))
    fail("nothing to resume at " + options.path + ": it is complete; run again with --overwrite to replace it");
  for (const std::string& p : {s->checkpoint, s->partial})
    if (!file_exists(p)) fail("nothing to resume at " + options.path + ": '" + p + "' does not exist");
  std::ifstream in(s->checkpoint, std::ios::binary);
  const std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  const Checkpoint c = parse(bytes, s->checkpoint);
  if (c.fingerprint != options.fingerprint)
    fail(s->checkpoint + " was written by a different run (input or options changed)");
  try {
    s->reopen_at(c.rows);
  } catch (const FileError& e) {
    fail(e.what());
  }
  s->rows = c.rows, s->cells = c.cells;
  *cells_committed = c.cells;
  return std::unique_ptr<MetadetectWriter>(new MetadetectWriter(std::move(s)));
}

void MetadetectWriter::append(std::span<const MetadetectRow> rows, long long cells) {
  State& s = *s_;
  if (s.failed || s.finished) fail("cannot append to '" + s.options.path + "': the writer is closed or failed");
  try {
    if (!rows.empty()) s.write_rows(rows);
    s.commit(s.rows + static_cast<long long>(rows.size()), s.cells + cells);
  } catch (const std::exception& e) {
    s.failed = true;
    if (s.rows == 0) throw;
    s.keep_for_resume = true;
    fail(std::string(e.what()) + "; the " + std::to_string(s.cells) + " cells committed before it are kept in '" +
         s.partial + "': make room, then run again with --resume");
  }
}

void MetadetectWriter::finish() {
  State& s = *s_;
  if (s.failed || s.finished) fail("cannot finish '" + s.options.path + "': the writer is closed or failed");
  bool unresumable = false;
  try {
    int status = 0;
    errno = 0;
    // The cells whose rows the table holds: a merge checks a shard against its range with it (a cell
    // may yield no rows).
    fits_update_key_lng(s.fits, "NCELLSW", s.cells, "cells whose rows this table holds", &status);
    s.check(status, "write key NCELLSW to");
    LONGLONG header_start = 0, data_start = 0, data_end = 0;
    fits_get_hduaddrll(s.fits, &header_start, &data_start, &data_end, &status);
    s.check(status, "locate the end of the table in");
    fits_close_file(s.fits, &status);
    const int error = errno;
    s.fits = nullptr;
    s.check(status, "close", error);
    s.file.sync();
    // The file must reach the table's end before it is named (unwritten_tail). A partial the close
    // cut is not resumable (the close rewrote committed blocks): it is removed, not kept.
    if (const std::string tail = unwritten_tail(s.partial, data_end); !tail.empty()) {
      unresumable = true;
      throw FileError(tail + "; the table is incomplete and was removed: make room, then run again (without --resume)");
    }
    s.close_quietly();
    rename_file(s.partial, s.options.path);
    remove_if_present(s.checkpoint);
    sync_directory_of(s.options.path);
    s.finished = true;
  } catch (const FileError& e) {
    s.failed = true;
    s.keep_for_resume = !unresumable && file_exists(s.partial);
    fail(e.what());
  }
}

void MetadetectWriter::abandon() noexcept {
  State& s = *s_;
  s.close_quietly();
  s.failed = true;
  if (s.keep_for_resume) return;
  std::error_code ignored;
  std::filesystem::remove(s.checkpoint, ignored);
  std::filesystem::remove(s.partial, ignored);
}

long long MetadetectWriter::rows() const { return s_->rows; }
long long MetadetectWriter::cells() const { return s_->cells; }

}  // namespace stampede::io
