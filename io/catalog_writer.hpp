// CatalogWriter: the output catalogue of `stampede fit`, written batch by batch so that a run
// killed at any moment (even kill -9 or a power cut) resumes without refitting committed objects.
//
// Outputs: a FITS binary table (EXTNAME 'RESULTS', one row per object) and optionally a whitespace
// text table with the same columns, written with the durable table's commit protocol
// (io/durable_table.hpp: PATH.partial and PATH.checkpoint while the run is in progress, each
// append() one commit, resume() cutting back to the last commit in raw bytes, finish() renaming).
//
// Columns: the schema in result_columns.hpp (catalog_columns() gives the names in order); units and
// descriptions are in the header as TUNITn / TCOMMn, the FitStatus values are named by the header
// keys STATUS0..STATUS6 and the flag bits listed in COMMENT cards. NaN is written as IEEE NaN in
// FITS and as "nan" in the text file (doubles are printed with 17 significant digits: they read
// back bitwise). catalog_reader.hpp reads the table back.
//
// Not thread-safe: one writer is driven by the pipeline's serial output stage.
#pragma once

#include <map>
#include <memory>
#include <span>
#include <string>
#include <utility>
#include <vector>

#include "io/catalog_error.hpp"
#include "engine/pipeline/object_record.hpp"
#include "io/header_value.hpp"
#include "io/result_columns.hpp"

namespace stampede::io {

struct CatalogWriterOptions {
  std::string path;         // final FITS path, e.g. out.fits (uncompressed: no .gz / .fz)
  std::string text_path;    // optional text catalogue with the same columns; "" = none
  PositionColumns positions = PositionColumns::kGrid;
  bool metacal = false;     // the metacal columns too (result_columns); the run's fingerprint covers it
  // Multi-band survey runs: each band's columns after the others (ResultSchema), the names in the
  // header key BANDS (comma-separated), which CatalogReader::bands() reads back.
  std::vector<std::string> bands;
  // Written as string-valued header keys of the table HDU in this order (a repeated key keeps its
  // last value); keys longer than 8 characters or outside [A-Z0-9_-] use the HIERARCH convention,
  // long values CONTINUE cards. Keys are stored upper-case (FITS lookups ignore case). Structural
  // keys (NAXIS2, TTYPE3, EXTNAME, STATUS0, ...) are refused. Ignored by resume(): the partial
  // file already has them, and the fingerprint vouches that they are unchanged.
  std::vector<std::pair<std::string, std::string>> header;
  // The type of each `header` key (as spelt there) whose value is a number: an integer or real
  // card where the value is one (io::write_header_key), so `stamp_size = 39` is not '39'. Keys not
  // listed are strings.
  std::map<std::string, HeaderValueType> header_types;
  // Identifies the run (its inputs' contents, configuration and program version), as lines of text:
  // resume() refuses a checkpoint written with a different fingerprint, positions layout or text
  // output, quoting the first line that differs.
  std::string fingerprint;
  // A failed append()/finish() after committed rows keeps the partials and the checkpoint through
  // abandon(), for resume(). False for a writer whose caller cannot resume (a merge, redone whole):
  // abandon() then removes everything, as after any other error.
  bool keep_on_write_failure = true;
};

class CatalogWriter {
 public:
  // Starts a new run: creates PATH.partial (and TEXT_PATH.partial), replacing stale ones and any
  // stale checkpoint, and commits zero rows. Throws CatalogError naming the path if it cannot be
  // created (e.g. the directory does not exist or is not writable), before any fitting is done.
  static std::unique_ptr<CatalogWriter> create(const CatalogWriterOptions& options);

  // Continues an interrupted run: reopens the partials, cuts them back to the rows recorded in the
  // checkpoint and stores that count in *rows_committed (if not null); the caller then appends
  // from that row on; with nothing committed (no checkpoint) the table starts afresh and
  // *rows_committed is 0. Throws CatalogError:
  //   "nothing to resume at PATH: it is complete ..."  PATH is there, with no partial or checkpoint;
  //   "nothing to resume at PATH: ..."  a checkpoint without its partial outputs;
  //   "PATH.checkpoint was written by a different run (input or configuration changed): it records
  //    'LINE', this run has 'LINE'" (the first fingerprint line that differs);
  //   "... is corrupt: ..."  the checkpoint or a partial cannot be what this writer left there.
  // *started (if not null): nothing was committed, the table was started anew.
  static std::unique_ptr<CatalogWriter> resume(const CatalogWriterOptions& options, long long* rows_committed,
                                               bool* started = nullptr);

  CatalogWriter(const CatalogWriter&) = delete;
  CatalogWriter& operator=(const CatalogWriter&) = delete;
  // Without finish(): closes the files, leaving the partials and checkpoint for resume(). Rows of
  // an append() that threw are not committed and will be cut on resume.
  ~CatalogWriter();

  // Appends `rows` after those already written and commits them (see the file comment). Memory
  // use is bounded by a fixed chunk, not by the batch or the table. After a throw the writer is
  // unusable (every later call throws); the outputs stay resumable at the last commit. A write
  // that fails (a full disk, `ulimit -f`, a quota, an I/O error) says what ran out where it can
  // tell (space_exhausted_reason) and, when rows were committed before it, that they are kept.
  void append(std::span<const ObjectRecord> rows);

  // Closes the outputs, renames the partials to PATH (and TEXT_PATH), replacing existing files,
  // and removes the checkpoint. Further calls other than rows() throw.
  void finish();

  // For a run that failed (an error, not a kill): closes and removes the partials and the checkpoint,
  // so that nothing is left that looks resumable; except after a failed append() or finish() with
  // rows committed, whose partials and checkpoint are kept for resume() (the failure was the
  // writer's own: the rows before it are good). Never throws; the writer is unusable after it.
  void abandon() noexcept;

  // Committed rows.
  long long rows() const;

 private:
  struct State;
  explicit CatalogWriter(std::unique_ptr<State> state);
  std::unique_ptr<State> s_;
};

}  // namespace stampede::io
