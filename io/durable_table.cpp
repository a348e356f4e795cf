// The durable table's commit protocol and crash repair; see durable_table.hpp.
#include "io/durable_table.hpp"

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <charconv>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <system_error>

#include "engine/common/quoted_value.hpp"
#include "io/durable_file.hpp"
#include "io/fits_cards.hpp"
#include "io/fits_error.hpp"

namespace stampede::io {
namespace {

constexpr std::string_view kMagic = "stampede table checkpoint 2";

[[noreturn]] void fail(const std::string& what) { throw CatalogError(what); }

std::string upper(std::string s) {
  for (char& c : s) c = static_cast<char>(std::toupper(static_cast<unsigned char>(c)));
  return s;
}

bool compressed_name(const std::string& path) {
  const std::string p = upper(path);
  return p.ends_with(".GZ") || p.ends_with(".FZ") || p.ends_with(".Z") || p.ends_with(".BZ2");
}

// The bytes a binary table's column of this TFORM takes in a row ("1D" 8, "7A" 7); 0 unknown.
long tform_width(const std::string& tform) {
  long repeat = 1;
  std::size_t at = 0;
  if (!tform.empty() && std::isdigit(static_cast<unsigned char>(tform[0]))) {
    const auto [end, ec] = std::from_chars(tform.data(), tform.data() + tform.size(), repeat);
    if (ec != std::errc()) return 0;
    at = static_cast<std::size_t>(end - tform.data());
  }
  if (at >= tform.size()) return 0;
  switch (tform[at]) {
    case 'L': case 'B': case 'A': return repeat;
    case 'I': return 2 * repeat;
    case 'J': case 'E': case 'V': return 4 * repeat;
    case 'K': case 'D': case 'C': return 8 * repeat;
    case 'M': return 16 * repeat;
    default: return 0;
  }
}

struct Checkpoint {
  long long rows = 0, units = 0, text_bytes = 0;
  std::string layout, fingerprint;
};

std::string serialise(const Checkpoint& c) {
  // Length-prefixed texts: a fingerprint may hold any byte, newlines included.
  return std::string(kMagic) + "\nrows " + std::to_string(c.rows) + "\nunits " + std::to_string(c.units) +
         "\ntext_bytes " + std::to_string(c.text_bytes) + "\nlayout " + std::to_string(c.layout.size()) + "\n" +
         c.layout + "\nfingerprint " + std::to_string(c.fingerprint.size()) + "\n" + c.fingerprint + "\nend\n";
}

// Throws "PATH is corrupt: ..." when `text` is not a checkpoint of this protocol.
Checkpoint parse(std::string_view text, const std::string& path) {
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
    if (l.starts_with(name) && l.size() > name.size() + 1 && l[name.size()] == ' ') {
      const char* last = l.data() + l.size();
      const auto [end, ec] = std::from_chars(l.data() + name.size() + 1, last, v);
      if (ec != std::errc() || end != last) v = -1;
    }
    if (v < 0) bad("a count is not a non-negative integer");
    return v;
  };
  auto block = [&](std::string_view name) {
    const auto n = static_cast<std::size_t>(number(name));
    if (n >= text.size()) bad("truncated text");
    std::string out(text.substr(0, n));
    text.remove_prefix(n);
    if (text.front() != '\n') bad("a text is not followed by a line end");
    text.remove_prefix(1);
    return out;
  };
  if (line() != kMagic) bad("not a stampede table checkpoint of this version");
  Checkpoint c;
  c.rows = number("rows");
  c.units = number("units");
  c.text_bytes = number("text_bytes");
  c.layout = block("layout");
  c.fingerprint = block("fingerprint");
  if (text != "end\n") bad("truncated or trailing bytes");
  return c;
}

void validate(const DurableTableOptions& o) {
  if (o.path.empty()) fail("table path is empty");
  if (compressed_name(o.path) || compressed_name(o.text_path)) {
    const std::string& p = compressed_name(o.path) ? o.path : o.text_path;
    fail("cannot write a compressed table '" + p + "' incrementally: write it uncompressed and compress it after the run");
  }
  if (!o.text_path.empty() && o.text_path == o.path) fail("text table path '" + o.text_path + "' is the FITS table path");
}

}  // namespace

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
  // A line in one fingerprint only is compared with those of the same key, not with the line at the
  // same place, which a file more or less (other PSFEx models found) would misalign.
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

struct DurableTable::State {
  DurableTableOptions options;
  std::string partial, text_partial, checkpoint, checkpoint_tmp;
  long row_width = 0;
  fitsfile* fits = nullptr;
  DurableFile fits_file;  // our descriptor of the FITS partial: fsync on it reaches CFITSIO's writes
  DurableFile text_file;
  long long rows = 0, units = 0, text_bytes = 0;  // committed
  long long text_pending = 0;                     // written since
  bool failed = false, finished = false;
  // A write failed after commits: abandon() keeps the partials and the checkpoint, which still
  // describe those rows, so the run resumes once room is made.
  bool keep_for_resume = false;

  explicit State(const DurableTableOptions& o)
      : options(o),
        partial(o.path + ".partial"),
        text_partial(o.text_path.empty() ? "" : o.text_path + ".partial"),
        checkpoint(o.path + ".checkpoint"),
        checkpoint_tmp(temporary_path(checkpoint)) {
    for (const TableColumn& c : o.columns) row_width += tform_width(c.tform);
  }
  State(const State&) = delete;
  State& operator=(const State&) = delete;
  // Closing with uncommitted rows is harmless: resume cuts back to the checkpoint.
  ~State() { close_quietly(); }

  bool has_text() const { return !text_partial.empty(); }

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

  void check(int status, const std::string& what, int error = 0) {
    if (status == 0) return;
    const std::string reason = status == WRITE_ERROR ? space_exhausted_reason(partial, error) : "";
    if (reason.empty()) fail("cannot " + what + " '" + partial + "': " + cfitsio_status_text(status));
    fits_clear_errmsg();
    fail("cannot " + what + " '" + partial + "': " + reason + " (CFITSIO status " + std::to_string(status) + ")");
  }

  void require_usable(const char* what) const {
    if (finished) fail(std::string("cannot ") + what + " '" + options.path + "': already finished");
    if (failed) fail(std::string("cannot ") + what + " '" + options.path + "': an earlier write failed; resume the run to continue");
  }

  void create_table(const StringKeys& header) {
    const int n = static_cast<int>(options.columns.size());
    std::vector<char*> ttype(n), tform(n), tunit(n);
    for (int i = 0; i < n; ++i) {  // CFITSIO takes char* but does not write through these
      ttype[i] = const_cast<char*>(options.columns[i].name.c_str());
      tform[i] = const_cast<char*>(options.columns[i].tform.c_str());
      tunit[i] = const_cast<char*>(options.columns[i].unit.c_str());
    }
    int status = 0;
    fits_create_tbl(fits, BINARY_TBL, 0, n, ttype.data(), tform.data(), tunit.data(), options.extname.c_str(), &status);
    check(status, "create the " + options.extname + " table in");
    for (int i = 0; i < n; ++i) {
      if (options.columns[i].comment.empty()) continue;
      const std::string key = "TCOMM" + std::to_string(i + 1);
      fits_write_key_str(fits, key.c_str(), options.columns[i].comment.c_str(), "", &status);
    }
    if (options.describe) options.describe(fits, &status);
    check(status, "write the table description to");
    std::map<std::string, HeaderValueType> types;  // by the upper-case key the header holds
    for (const auto& [key, type] : options.header_types) types[upper(key)] = type;
    for (const auto& [key, value] : header) {
      const auto type = types.find(key);
      write_header_key(fits, key, value, type == types.end() ? HeaderValueType::kText : type->second, &status);
      check(status, "write header key '" + key + "' to");
    }
    if (options.reserved_keys > 0) fits_set_hdrsize(fits, options.reserved_keys, &status);
    check(status, "reserve header room in");
  }

  // Flushes and syncs the partials, checks that the FITS one reaches the table's end, and records
  // the new counts in the checkpoint.
  void commit(long long new_rows, long long new_units) {
    int status = 0;
    errno = 0;
    fits_flush_file(fits, &status);  // also rewrites NAXIS2 and the data fill
    check(status, "write", errno);
    fits_file.sync();
    LONGLONG header_start = 0, data_start = 0, data_end = 0;
    fits_get_hduaddrll(fits, &header_start, &data_start, &data_end, &status);
    check(status, "locate the end of the table in");
    if (const std::string tail = unwritten_tail(partial, data_end); !tail.empty()) fail(tail);
    if (has_text()) text_file.sync();
    replace_durably(checkpoint,
                    serialise({new_rows, new_units, text_bytes + text_pending, options.layout, options.fingerprint}));
    rows = new_rows, units = new_units;
    text_bytes += text_pending;
    text_pending = 0;
  }

  // Cuts the FITS partial back to `committed` rows (see the file comment).
  void repair_fits(long long committed) {
    const std::string corrupt = partial + " is corrupt: ";
    int status = 0;
    fits_open_diskfile(&fits, partial.c_str(), READONLY, &status);
    if (status != 0) {
      fits = nullptr;
      fail(corrupt + "cannot open it as FITS: " + cfitsio_status_text(status));
    }
    LONGLONG naxis1 = 0, naxis2 = 0, header_start = 0, data_start = 0, data_end = 0;
    int hdunum = 0, ncols = 0;
    fits_movnam_hdu(fits, BINARY_TBL, const_cast<char*>(options.extname.c_str()), 0, &status);
    fits_get_hdu_num(fits, &hdunum);
    fits_get_num_cols(fits, &ncols, &status);
    fits_read_key(fits, TLONGLONG, "NAXIS1", &naxis1, nullptr, &status);
    fits_get_num_rowsll(fits, &naxis2, &status);
    fits_get_hduaddrll(fits, &header_start, &data_start, &data_end, &status);
    if (status != 0) {
      const std::string why = cfitsio_status_text(status);
      close_quietly();
      fail(corrupt + "no readable " + options.extname + " table: " + why);
    }
    std::string why;
    if (hdunum != 2 || ncols != static_cast<int>(options.columns.size()) || naxis1 != row_width)
      why = "its " + options.extname + " table does not have this run's layout";
    for (int c = 0; c < ncols && why.empty(); ++c) {
      char name[FLEN_VALUE] = {};
      const std::string key = "TTYPE" + std::to_string(c + 1);
      int key_status = 0;
      fits_read_key(fits, TSTRING, key.c_str(), name, nullptr, &key_status);
      if (key_status != 0 || options.columns[static_cast<std::size_t>(c)].name != std::string(name)) {
        why = "column " + std::to_string(c + 1) + " is not '" + options.columns[static_cast<std::size_t>(c)].name + "'";
        if (key_status != 0) fits_clear_errmsg();
      }
    }
    close_quietly();
    if (!why.empty()) fail(corrupt + why);
    if (naxis2 < committed)
      fail(corrupt + "it has " + std::to_string(naxis2) + " rows but " + checkpoint + " commits " + std::to_string(committed));

    const long long committed_end = data_start + committed * naxis1;
    const long long padded = (committed_end + 2879) / 2880 * 2880;
    fits_file = DurableFile::open(partial, DurableFile::Mode::kReadWrite);
    if (fits_file.size() < committed_end)
      fail(corrupt + "it is shorter than the " + std::to_string(committed) + " committed rows");
    // Truncating then extending zeroes the fill: rows past NAXIS2, or a partial block, may have
    // reached the disk before the run stopped.
    fits_file.truncate(committed_end);
    fits_file.truncate(padded);
    fits_file.sync();
    fits_file = DurableFile();

    fits_open_diskfile(&fits, partial.c_str(), READWRITE, &status);
    if (status != 0) {
      fits = nullptr;
      check(status, "reopen");
    }
    fits_movabs_hdu(fits, 2, nullptr, &status);
    if (naxis2 != committed) {
      // "&" keeps the card's comment, so the header is an uninterrupted run's.
      fits_update_key_lng(fits, "NAXIS2", committed, "&", &status);
      fits_set_hdustruc(fits, &status);  // re-read the structure after changing NAXIS2
      fits_flush_file(fits, &status);
    }
    check(status, "restore the committed rows of");
    fits_file = DurableFile::open(partial, DurableFile::Mode::kRead);
    fits_file.sync();
  }

  // Cuts the text partial back to `committed` bytes, checking that they end a line of this layout.
  void repair_text(long long committed) {
    const std::string corrupt = text_partial + " is corrupt: ";
    const std::string& head_expected = options.text_header;
    text_file = DurableFile::open(text_partial, DurableFile::Mode::kReadWrite);
    const long long size = text_file.size();
    if (size < committed || committed < static_cast<long long>(head_expected.size()))
      fail(corrupt + "it is shorter than the committed " + std::to_string(committed) + " bytes");
    std::string head(head_expected.size(), '\0');
    char last = 0;
    text_file.read_at(0, head);
    text_file.read_at(committed - 1, std::span<char>(&last, 1));
    if (head != head_expected) fail(corrupt + "its header line is not this run's columns");
    if (last != '\n') fail(corrupt + "the committed bytes do not end a line");
    text_file.truncate(committed);
    text_file.seek_to_end();
    text_file.sync();
  }

  // "; the N units committed [before it] are kept ...", for a failure after commits.
  std::string kept_note(const char* when) const {
    return "; the " + std::to_string(units) + " " + options.units + " committed " + when + "are kept in '" + partial +
           "' (with '" + checkpoint + "'): make room, then resume the run (--resume)";
  }
};

DurableTable::DurableTable(std::unique_ptr<State> s) : s_(std::move(s)) {}
DurableTable::~DurableTable() = default;

std::unique_ptr<DurableTable> DurableTable::create(const DurableTableOptions& options) {
  validate(options);
  ignore_file_size_signal();  // a write past `ulimit -f` fails (EFBIG, reported) instead of killing the process
  StringKeys header;
  std::string why;
  if (!normalise_string_keys(options.header, &header, &why)) fail(why);
  auto s = std::make_unique<State>(options);
  try {
    // A stale checkpoint must not outlive the partials it described.
    remove_if_present(s->checkpoint);
    remove_if_present(s->checkpoint_tmp);
    // Up-front check with the errno text: CFITSIO only says "couldn't create the named file".
    // fits_create_diskfile refuses an existing file, so the FITS probe is removed again.
    DurableFile::create(s->partial, "table");
    if (s->has_text()) s->text_file = DurableFile::create(s->text_partial, "table");
    remove_if_present(s->partial);
    int status = 0;
    fits_create_diskfile(&s->fits, s->partial.c_str(), &status);
    if (status != 0) {
      s->fits = nullptr;
      s->check(status, "create table");
    }
    s->create_table(header);
    s->fits_file = DurableFile::open(s->partial, DurableFile::Mode::kRead);
    if (s->has_text()) {
      s->text_file.write_all(options.text_header);
      s->text_pending = static_cast<long long>(options.text_header.size());
      // The checkpoint's rename syncs the FITS directory; the text may live elsewhere.
      if (directory_of(s->text_partial) != directory_of(s->partial)) sync_directory_of(s->text_partial);
    }
    s->commit(0, 0);
  } catch (...) {
    // Leave nothing that resume could mistake for a run.
    s->close_quietly();
    std::error_code ignored;
    for (const std::string& p : {s->checkpoint, s->checkpoint_tmp, s->partial, s->text_partial})
      if (!p.empty()) std::filesystem::remove(p, ignored);
    try {
      throw;
    } catch (const FileError& e) {
      fail(e.what());
    }
  }
  return std::unique_ptr<DurableTable>(new DurableTable(std::move(s)));
}

std::unique_ptr<DurableTable> DurableTable::resume(const DurableTableOptions& options, Committed* committed) {
  validate(options);
  ignore_file_size_signal();
  auto s = std::make_unique<State>(options);
  const bool has_checkpoint = file_exists(s->checkpoint);
  if (!has_checkpoint && !file_exists(s->partial) && file_exists(options.path))
    fail("nothing to resume at " + options.path + ": it is complete (finished, so it has no '" + s->checkpoint +
         "'); run it again with --overwrite to replace it");
  if (!has_checkpoint) {  // nothing was committed: the run starts (a stale partial is replaced)
    *committed = {0, 0, true};
    return create(options);
  }
  for (const std::string& p : {s->partial, s->text_partial})
    if (!p.empty() && !file_exists(p))
      fail("nothing to resume at " + options.path + ": '" + p + "' does not exist (its checkpoint '" + s->checkpoint +
           "' is left from a run " +
           (file_exists(options.path) ? "that finished, stopped as it removed the checkpoint: remove the checkpoint"
                                      : "whose table is gone: run again with --overwrite") + ")");
  std::string bytes;
  {
    std::ifstream in(s->checkpoint, std::ios::binary);
    bytes.assign(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
    if (in.bad()) fail("cannot read '" + s->checkpoint + "'");
  }
  const Checkpoint c = parse(bytes, s->checkpoint);
  if (c.fingerprint != options.fingerprint || c.layout != options.layout || (c.text_bytes > 0) != s->has_text()) {
    std::string difference = first_difference(c.fingerprint, options.fingerprint);
    if (difference.empty() && c.layout != options.layout)
      difference = ": it records the layout '" + c.layout + "', this run has '" + options.layout + "'";
    if (difference.empty()) difference = s->has_text() ? ": it has no text table, this run has one" : ": it has a text table, this run has none";
    fail(s->checkpoint + " was written by a different run (input or configuration changed)" + difference);
  }
  try {
    s->repair_fits(c.rows);
    if (s->has_text()) s->repair_text(c.text_bytes);
  } catch (const FileError& e) {
    s->close_quietly();
    fail(e.what());
  }
  s->rows = c.rows, s->units = c.units, s->text_bytes = c.text_bytes;
  *committed = {c.rows, c.units, false};
  return std::unique_ptr<DurableTable>(new DurableTable(std::move(s)));
}

fitsfile* DurableTable::fits() { return s_->fits; }

void DurableTable::check(int status, const std::string& what, int error) { s_->check(status, what, error); }

void DurableTable::write_text(std::string_view bytes) {
  s_->text_file.write_all(bytes);
  s_->text_pending += static_cast<long long>(bytes.size());
}

void DurableTable::append(long long rows, long long units, const std::function<void()>& write) {
  State& s = *s_;
  s.require_usable("append to");
  try {
    try {
      write();
      s.commit(s.rows + rows, s.units + units);
    } catch (const FileError& e) {
      fail(e.what());
    }
  } catch (const CatalogError& e) {
    s.failed = true;
    if (s.units == 0 || !s.options.keep_on_write_failure) throw;
    s.keep_for_resume = true;
    fail(e.what() + s.kept_note("before it "));
  } catch (...) {
    s.failed = true;
    throw;
  }
}

void DurableTable::finish(const std::vector<FinalKey>& keys) {
  State& s = *s_;
  s.require_usable("finish");
  try {
    try {
      int status = 0;
      for (const FinalKey& k : keys) {
        fits_update_key_lng(s.fits, k.key.c_str(), k.value, k.comment.c_str(), &status);
        s.check(status, "write key " + k.key + " to");
      }
      errno = 0;
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
      if (s.has_text()) s.text_file.sync();
      s.close_quietly();
      // CFITSIO's close writes the last blocks and can lose a short write there: the file must
      // reach its end before it is named.
      if (const std::string tail = unwritten_tail(s.partial, data_end); !tail.empty()) fail(tail);
      // The text first: once the FITS file has its final name the run counts as done.
      if (s.has_text()) {
        rename_file(s.text_partial, s.options.text_path);
        sync_directory_of(s.options.text_path);
      }
      rename_file(s.partial, s.options.path);
      remove_if_present(s.checkpoint);
      remove_if_present(s.checkpoint_tmp);
      sync_directory_of(s.options.path);
      s.finished = true;
    } catch (const FileError& e) {
      fail(e.what());
    }
  } catch (const CatalogError& e) {
    s.failed = true;
    s.close_quietly();
    // Until the FITS partial is renamed the run is resumable at its last commit; after, it is done.
    if (s.units == 0 || !s.options.keep_on_write_failure || !file_exists(s.partial)) throw;
    s.keep_for_resume = true;
    fail(e.what() + s.kept_note(""));
  } catch (...) {
    s.failed = true;
    throw;
  }
}

void DurableTable::abandon() noexcept {
  State& s = *s_;
  s.close_quietly();
  s.failed = true;
  std::error_code ignored;
  std::filesystem::remove(s.checkpoint_tmp, ignored);
  if (s.keep_for_resume) return;
  for (const std::string& p : {s.checkpoint, s.partial, s.text_partial})
    if (!p.empty()) std::filesystem::remove(p, ignored);
}

long long DurableTable::rows() const { return s_->rows; }
long long DurableTable::units() const { return s_->units; }

}  // namespace stampede::io
