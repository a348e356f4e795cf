// A FITS binary table that a run writes in commits, crash-safe and resumable: the commit protocol
// of every table a run writes. The fit catalogue (io/catalog_writer) and the metadetect table
// (io/metadetect_writer) are two schemas over it: their columns, header description and row
// writes.
//
// While the run is in progress the table lives at PATH.partial (with an optional text companion at
// TEXT.partial) beside PATH.checkpoint. A commit (append):
//   1. the schema writes its rows (column writes to fits(), lines through write_text);
//   2. the partials are flushed and fsync'd, and the FITS partial is checked to reach the table's
//      data end: CFITSIO writes through stdio, which can lose a failed buffered write (a file-size
//      limit or a full disk) and report success, so the file's length is the proof;
//   3. PATH.checkpoint is replaced atomically (durable_file.hpp) with the committed rows, the units
//      (what the run resumes by: objects, cells), the text bytes, the layout and the fingerprint.
// So the checkpoint never counts a row that is not on disk.
//
// resume() repairs the partials in raw bytes before CFITSIO writes to them: whatever a kill, a
// full disk or a file-size limit left after the committed rows (rows, a partial block, a header
// whose NAXIS2 ran ahead) is cut, the last block's fill zeroed and NAXIS2 restored, which is the
// file as it was at that commit; the resumed table is byte for byte an uninterrupted run's. A
// resume with nothing committed (no checkpoint: the run failed or was killed before its first
// commit) starts the table afresh (Committed::fresh).
//
// finish() sets the keys reserved at creation (their room is made then, so the header never grows
// at the end and committed blocks never move), closes, checks that the file reaches its end, and
// renames the partials into place. A finish that fails keeps the committed rows for resume.
//
// Every failure throws CatalogError naming the file; a write that ran out of room says what ran out
// (space_exhausted_reason). Not thread-safe: a run's serial output stage drives it.
//
// Includes fitsio.h: include this only from the .cpp files of the schemas.
#pragma once

#include <fitsio.h>

#include <functional>
#include <map>
#include <memory>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "io/catalog_error.hpp"
#include "io/header_value.hpp"
#include "io/table_writer.hpp"

namespace stampede::io {

struct TableColumn {
  std::string name;
  std::string tform;    // 1K 1J 1V 1D 7A ...
  std::string unit;     // TUNITn; "" none
  std::string comment;  // TCOMMn; "" none
};

struct DurableTableOptions : TableWriterOptions {  // path, header and its types, fingerprint
  std::string text_path;  // the text companion's final path; "" none
  std::string text_header;  // the text companion's first line(s), checked on resume
  std::string extname;    // the table HDU's EXTNAME
  std::vector<TableColumn> columns;
  // The schema's own header cards (status names, comments), written after the columns' and before
  // `header`. CFITSIO's status convention.
  std::function<void(fitsfile*, int* status)> describe;
  // The table's layout (the schema's variant): a resume refuses a checkpoint of another.
  std::string layout;
  int reserved_keys = 0;        // how many keys finish() adds
  std::string units = "rows";  // what the run resumes by, in messages ("cells")
  // A failed append or finish after committed rows keeps the partials and the checkpoint through
  // abandon(), for resume. False for a caller that cannot resume (a merge, redone whole).
  bool keep_on_write_failure = true;
};

class DurableTable {
 public:
  struct Committed {
    long long rows = 0, units = 0;
    bool fresh = false;  // nothing was committed: the table was created anew
  };
  // Starts the table: PATH.partial (and TEXT.partial) created, stale ones and any stale checkpoint
  // replaced, zero rows committed. Throws CatalogError before any row is written.
  static std::unique_ptr<DurableTable> create(const DurableTableOptions& options);
  // Continues an interrupted run (see the file comment). Throws CatalogError:
  //   "nothing to resume at PATH: it is complete ..."  PATH is there, with no partial or checkpoint;
  //   "PATH.checkpoint was written by a different run ...: it records 'A', this run has 'B'";
  //   "... is corrupt: ..."  a checkpoint or partial that this protocol cannot have left.
  static std::unique_ptr<DurableTable> resume(const DurableTableOptions& options, Committed* committed);

  DurableTable(const DurableTable&) = delete;
  DurableTable& operator=(const DurableTable&) = delete;
  // Without finish(): closes, leaving the partials and checkpoint for resume.
  ~DurableTable();

  // One commit: `write` writes rows [rows(), rows() + rows) through fits(), check() and
  // write_text(); then they are committed with `units` more units. After a throw the table is
  // unusable; a failure after earlier commits says that they are kept for resume.
  void append(long long rows, long long units, const std::function<void()>& write);
  fitsfile* fits();
  // Throws CatalogError "cannot WHAT 'PARTIAL': why" for a non-zero CFITSIO status; `error` is
  // errno just after the failed call (what ran out, for a write).
  void check(int status, const std::string& what, int error = 0);
  void write_text(std::string_view bytes);

  void finish(const std::vector<FinalKey>& keys = {});
  // A failed run: closes, and removes the partials and the checkpoint unless a write failed after
  // commits (then kept for resume). Never throws.
  void abandon() noexcept;

  long long rows() const;
  long long units() const;

 private:
  struct State;
  explicit DurableTable(std::unique_ptr<State> s);
  std::unique_ptr<State> s_;
};

// What differs between two fingerprints, as ": it records 'A', this run has 'B'" ("" when they
// hold the same lines). Lines are "KEY=value" or "role path: digest"; an option changed is named
// first, then a file of the same role, then whatever differs.
std::string first_difference(std::string_view recorded, std::string_view current);

}  // namespace stampede::io
