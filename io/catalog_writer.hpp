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

#include <memory>
#include <span>
#include <string>
#include <vector>

#include "engine/pipeline/object_record.hpp"
#include "io/result_columns.hpp"
#include "io/table_writer.hpp"

namespace stampede::io {

struct CatalogWriterOptions : TableWriterOptions {  // path, header and its types, fingerprint
  std::string text_path;    // optional text catalogue with the same columns; "" = none
  PositionColumns positions = PositionColumns::kGrid;
  bool metacal = false;     // the metacal columns too (result_columns); the run's fingerprint covers it
  // Multi-band survey runs: each band's columns after the others (ResultSchema), the names in the
  // header key BANDS (comma-separated), which CatalogReader::bands() reads back.
  std::vector<std::string> bands;
  // A failed append()/finish() after committed rows keeps the partials and the checkpoint through
  // abandon(), for resume. False for a writer whose caller cannot resume (a merge, redone whole):
  // abandon() then removes everything, as after any other error.
  bool keep_on_write_failure = true;
};

class CatalogWriter final : public TableWriter {
 public:
  // Starts a new run: creates PATH.partial (and TEXT_PATH.partial), replacing stale ones and any
  // stale checkpoint, and commits zero rows. Throws CatalogError naming the path if it cannot be
  // created (e.g. the directory does not exist or is not writable), before any fitting is done.
  static std::unique_ptr<CatalogWriter> create(const CatalogWriterOptions& options);

  // Continues an interrupted run: reopens the partials and cuts them back to the rows recorded in
  // the checkpoint (units()); the caller then appends from that row on; with nothing committed (no
  // checkpoint) the table starts afresh (started_afresh()). Throws CatalogError:
  //   "nothing to resume at PATH: it is complete ..."  PATH is there, with no partial or checkpoint;
  //   "nothing to resume at PATH: ..."  a checkpoint without its partial outputs;
  //   "PATH.checkpoint was written by a different run (input or configuration changed): it records
  //    'LINE', this run has 'LINE'" (the first fingerprint line that differs);
  //   "... is corrupt: ..."  the checkpoint or a partial cannot be what this writer left there.
  static std::unique_ptr<CatalogWriter> resume(const CatalogWriterOptions& options);

  // Without finish(): closes the files, leaving the partials and checkpoint for resume(). Rows of
  // an append() that threw are not committed and will be cut on resume.
  ~CatalogWriter() override;

  // Appends `rows` after those already written and commits them (see the file comment). Memory
  // use is bounded by a fixed chunk, not by the batch or the table. After a throw the writer is
  // unusable (every later call throws); the outputs stay resumable at the last commit. A write
  // that fails (a full disk, `ulimit -f`, a quota, an I/O error) says what ran out where it can
  // tell (space_exhausted_reason) and, when rows were committed before it, that they are kept.
  void append(std::span<const ObjectRecord> rows);

 private:
  struct State;
  CatalogWriter(const CatalogWriterOptions& options, bool resume);
  std::unique_ptr<State> s_;
};

}  // namespace stampede::io
