// The catalogue of `stampede metadetect`: a FITS binary table (EXTNAME 'METADETECT'), a row per
// (cell, shear type, detection) and one flagged row per cell that could not be measured, written
// cell batch by cell batch so that a killed run resumes without remeasuring committed cells.
//
// The commit protocol is the durable table's (io/durable_table.hpp), whose units here are cells (a
// cell yields any number of rows, so the run resumes at the next cell, not row); finish() records
// the cells in header key NCELLSW (its room reserved at creation) and renames the partial to PATH.
// resume() refuses a checkpoint of another run (the fingerprint: inputs' digests, options, version).
//
// Columns (TUNITn, TCOMMn in the header): cell, shear_type, the row's fields
// (metadetect_field_columns: id x y ... flags, the PSF's, the unsheared position and mask bits),
// then [flux_<band>... snr_<band>...]. Not thread-safe: the pipeline's serial output stage drives it.
#pragma once
#include <memory>
#include <span>
#include <string>
#include <vector>

#include "engine/metadetect/metadetect_row.hpp"
#include "io/table_writer.hpp"

namespace stampede::io {

struct MetadetectWriterOptions : TableWriterOptions {  // path, header and its types, fingerprint
  // Band names (several bands, or one named): columns flux_<band> and snr_<band> after the
  // others, from each row's band_flux and band_snr.
  std::vector<std::string> bands;
};

// A column that holds a row's field (every column but cell, shear_type and the bands'): what the
// writer writes and io/metadetect_reader reads back, listed once.
struct MetadetectColumn {
  const char* name;
  const char* tform;  // "1D" or "1J"
  const char* unit;
  const char* comment;
  double (*get)(const MetadetectRow&);  // the field's value (an integer's exact)
  void (*set)(MetadetectRow&, double);
  bool optional;  // added later: a table written before it lacks it (its rows keep the default)
};
// In the table's order, after cell and shear_type.
std::span<const MetadetectColumn> metadetect_field_columns();

class MetadetectWriter final : public TableWriter {
 public:
  // Throws CatalogError naming the path.
  static std::unique_ptr<MetadetectWriter> create(const MetadetectWriterOptions& options);
  // Continues an interrupted run at units(), the cells whose rows are all on disk (afresh when
  // nothing was committed: started_afresh()).
  static std::unique_ptr<MetadetectWriter> resume(const MetadetectWriterOptions& options);
  ~MetadetectWriter() override;
  // Appends the rows of the next `cells` cells and commits them.
  void append(std::span<const MetadetectRow> rows, long long cells);
  // Records the cells in NCELLSW (a merge checks a shard against its range with it: a cell may
  // yield no rows) and the rows in NROWSW (a merge refuses a shard that lost some), then finishes
  // the table.
  void finish() override;

 private:
  struct State;
  MetadetectWriter(const MetadetectWriterOptions& options, bool resume);
  std::unique_ptr<State> s_;
};

}  // namespace stampede::io
