// A run's table as the run harness (app/run_harness) drives it: a schema — the fit catalogue
// (io/catalog_writer), the metadetect table (io/metadetect_writer) — over the durable table's
// commit protocol (io/durable_table.hpp). A schema adds its columns and its append; creating,
// resuming, finishing and abandoning the table are this base's, the same for every schema.
#pragma once

#include <map>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "io/catalog_error.hpp"
#include "io/header_value.hpp"

namespace stampede::io {

class DurableTable;
struct DurableTableOptions;

// An integer key a table gains when it is finished (NCELLSW); its room is reserved at creation.
struct FinalKey {
  std::string key;
  long long value = 0;
  std::string comment;
};

// What every schema's options hold: the table's path and the run's identity in it.
struct TableWriterOptions {
  std::string path;  // final FITS path, e.g. out.fits (uncompressed: no .gz / .fz)
  // Written as string-valued header keys of the table HDU in this order (a repeated key keeps its
  // last value); keys longer than 8 characters or outside [A-Z0-9_-] use the HIERARCH convention,
  // long values CONTINUE cards. Keys are stored upper-case (FITS lookups ignore case). Structural
  // keys (NAXIS2, TTYPE3, EXTNAME, ...) are refused. Ignored by a resume: the partial file already
  // has them, and the fingerprint vouches that they are unchanged.
  std::vector<std::pair<std::string, std::string>> header;
  // The type of each `header` key whose value is a number: an integer or real card where the value
  // is one (io::write_header_key). Keys not listed are strings.
  std::map<std::string, HeaderValueType> header_types;
  // Identifies the run (its inputs' contents, configuration and program version), as lines of text:
  // a resume refuses a checkpoint written with another, quoting the first line that differs.
  std::string fingerprint;
};

class TableWriter {
 public:
  virtual ~TableWriter();
  TableWriter(const TableWriter&) = delete;
  TableWriter& operator=(const TableWriter&) = delete;

  // Closes the table, renames the partials into place and removes the checkpoint. A finish that
  // fails keeps the committed rows for resume.
  virtual void finish();
  // For a run that failed (an error, not a kill): removes the partials and the checkpoint, except
  // after a failed append or finish with rows committed (kept for resume). Never throws.
  void abandon() noexcept;

  long long rows() const;   // committed rows
  long long units() const;  // committed units (objects, cells): where a resumed run continues
  bool started_afresh() const { return started_afresh_; }  // a resume that found nothing committed

 protected:
  TableWriter();
  // Creates the table, or with `resume` continues it (afresh when nothing was committed). Throws
  // CatalogError naming the file (io/durable_table.hpp lists the refusals).
  void open(const DurableTableOptions& options, bool resume);
  DurableTable& table() { return *table_; }

 private:
  std::unique_ptr<DurableTable> table_;
  bool started_afresh_ = false;
};

}  // namespace stampede::io
